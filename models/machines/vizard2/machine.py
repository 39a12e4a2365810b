"""VIZARD II (``ray``) as a :class:`Machine`.

# Ref: architectures.md section 6 (VIZARD II); docs/cycle.md (the VIZARD II model).
"""

from __future__ import annotations

from typing import Any

from models.machines import Machine, single_frames
from models.machines.vizard2.config import VizardFaults
from models.machines.vizard2.cycle import VizardMachine
from models.machines.vizard2.transaction import VizardTransaction


def transaction(scene, arch, plan, **frame: Any) -> VizardTransaction:
    """The ray-packet event model; it reads the volume (the block cache's misses)."""
    return VizardTransaction(scene, arch, plan, **frame)


MACHINE = Machine(
    name="vizard2",
    orders=("ray",),
    cycle=single_frames(VizardMachine),
    transaction=transaction,
    faults_type=VizardFaults,
    package="models.machines.vizard2",
)
