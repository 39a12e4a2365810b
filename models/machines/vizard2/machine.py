"""VIZARD II (``ray``) as a :class:`Machine`.

# Ref: architectures.md section 6 (VIZARD II); docs/cycle.md (the VIZARD II model).
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.vizard2 import silicon
from models.machines.vizard2.config import VizardBuffers, VizardFaults, check_arch, check_frame
from models.machines.vizard2.cycle import VizardMachine
from models.machines.vizard2.transaction import VizardTransaction

MACHINE = Machine(
    name="vizard2",
    orders=("ray",),
    cycle=single_frames(VizardMachine),
    transaction=VizardTransaction,  # reads the volume (the block cache's misses)
    faults_type=VizardFaults,
    check_frame=check_frame,
    package="models.machines.vizard2",
    silicon=silicon.silicon,
    accesses=silicon.accesses,
    buffers=VizardBuffers,
    check_arch=check_arch,
)
