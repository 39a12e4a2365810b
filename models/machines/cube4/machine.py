"""The Cube-4 family (``slice-parallel``: ``cube4``, ``cube4-teramac``) as a :class:`Machine`.

# Ref: architectures.md section 1 (Cube-4); docs/cycle.md (the Cube-4 cycle model).
"""

from __future__ import annotations

from typing import Any

from models.machines import Machine, single_frames
from models.machines.cube4.cycle import Cube4Machine, Faults
from models.machines.cube4.transaction import Cube4Transaction


def transaction(
    scene, arch, plan, *, volume=None, transfer=None, stopped=None, datapath=None, **options: Any
) -> Cube4Transaction:
    """The Cube-4 event model; it reads neither the volume nor the rays' ends."""
    return Cube4Transaction(scene, arch, plan, **options)


MACHINE = Machine(
    name="cube4",
    orders=("slice-parallel",),
    cycle=single_frames(Cube4Machine),
    transaction=transaction,
    faults_type=Faults,
    rtl_top="rtl.top",
    package="models.machines.cube4",
)
