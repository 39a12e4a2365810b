"""Cube-1 (``slice-parallel`` beams from the six axis views) as a :class:`Machine`.

# Ref: architectures.md section 1.1 (Cube-1/Cube-2); docs/early-machines.md (the Cube-1 model).
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.cube1.cycle import Cube1Machine
from models.machines.cube1.frame import Cube1Buffers, Cube1Faults, check_frame
from models.machines.cube1.transaction import Cube1Transaction

MACHINE = Machine(
    name="cube1",
    orders=("slice-parallel",),
    cycle=single_frames(Cube1Machine),
    transaction=Cube1Transaction,  # reads neither the volume nor the rays' ends
    faults_type=Cube1Faults,
    check_frame=check_frame,
    package="models.machines.cube1",
    buffers=Cube1Buffers,
    independence={
        "verdict": "partly shared",
        "shared": (
            "models.machines.cube1.frame.bus_levels",
            "models.functional.pipeline_latency",
        ),
        "txn": "ceil(L / n) accesses for every column of the buffer along the view axis, "
        "from the skewing's theorem (Cube1Transaction.run)",
        "cycle": "each beam's busiest module, counted from the modules of its voxels "
        "(CubicFrameBuffer.module_of, common.skewed.beam_cycles)",
    },
)
