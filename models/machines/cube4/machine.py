"""The Cube-4 family (``slice-parallel``: ``cube4``, ``cube4-teramac``) as a :class:`Machine`.

# Ref: architectures.md section 1 (Cube-4); docs/cycle.md (the Cube-4 cycle model).
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.cube4 import silicon
from models.machines.cube4.bands import BandSplit
from models.machines.cube4.cycle import Cube4Machine, Faults
from models.machines.cube4.frame import Cube4Buffers, check_cube4_frame
from models.machines.cube4.transaction import Cube4Transaction

MACHINE = Machine(
    name="cube4",
    orders=("slice-parallel",),
    cycle=single_frames(Cube4Machine),
    transaction=Cube4Transaction,  # reads neither the volume nor the rays' ends
    faults_type=Faults,
    check_frame=check_cube4_frame,
    rtl_top="rtl.top",
    package="models.machines.cube4",
    silicon=silicon.silicon,
    accesses=silicon.accesses,
    split=BandSplit,
    buffers=Cube4Buffers,
    skew_memory=True,
)
