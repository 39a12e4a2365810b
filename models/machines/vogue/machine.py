"""VOGUE (``ray``: host-defined rays, one per module at a time, a ring) as a :class:`Machine`.

# Ref: the overview's VOGUE paragraph [V]; docs/early-machines.md (the VOGUE model).
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.vogue.config import VogueBuffers, check_frame
from models.machines.vogue.cycle import VogueMachine
from models.machines.vogue.transaction import VogueTransaction

MACHINE = Machine(
    name="vogue",
    orders=("ray",),
    cycle=single_frames(VogueMachine),
    transaction=VogueTransaction,  # reads neither the volume nor the rays' ends
    check_frame=check_frame,
    package="models.machines.vogue",
    buffers=VogueBuffers,
    independence={
        "verdict": "partly shared",
        "shared": (
            "models.machines.vogue.config.parse_buffers",
            "models.machines.vogue.config.voxel_bytes",
            "models.functional.pipeline_latency",
        ),
        "txn": "the frame's work spread evenly over the boards, ceil(W / B), and each link "
        "carrying (B - 1) / B of the volume (VogueTransaction.run)",
        "cycle": "rays dispatched one by one to the module free first (module_loads) and "
        "each link's bytes from the boards' z-slabs (config.ring_link_bytes)",
    },
)
