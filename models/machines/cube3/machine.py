"""Cube-3 (``ray``: skewed memory, barrel-shifter network, parallel units, compositing
tree) as a :class:`Machine`.

# Ref: models.machines.cube3.frame (sources); docs/early-machines.md (the Cube-3 model).
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.cube3.cycle import Cube3Machine
from models.machines.cube3.frame import Cube3Buffers, Cube3Faults, check_frame
from models.machines.cube3.transaction import Cube3Transaction

MACHINE = Machine(
    name="cube3",
    orders=("ray",),
    cycle=single_frames(Cube3Machine),
    transaction=Cube3Transaction,  # reads neither the volume nor the rays' ends
    faults_type=Cube3Faults,
    check_frame=check_frame,
    package="models.machines.cube3",
    buffers=Cube3Buffers,
    independence={
        "verdict": "partly shared",
        "shared": (
            "models.machines.cube3.frame.slab_arrivals",
            "models.machines.cube3.frame.slice_beams",
            "models.machines.cube3.frame.LOOKAHEAD",
            "models.machines.cube3.frame.tree_levels",
            "models.machines.cube3.frame.parse_buffers",
            "models.functional.pipeline_latency",
        ),
        "txn": "the plan's samples spread evenly over the slabs and the max-plus closed "
        "form of the two-stage pipeline (Cube3Transaction.run)",
        "cycle": "each slab's samples counted from the plan's positions (slab_loads) and "
        "the slab-by-slab recurrence (frame.slab_schedule)",
    },
)
