"""VIRIM (``ray``) as a :class:`Machine`.

# Ref: docs/architectures.md ("VIRIM").
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.virim.config import VirimBuffers
from models.machines.virim.cycle import VirimMachine
from models.machines.virim.transaction import VirimTransaction

MACHINE = Machine(
    name="virim",
    orders=("ray",),
    cycle=single_frames(VirimMachine),
    transaction=VirimTransaction,
    package="models.machines.virim",
    buffers=VirimBuffers,
    independence={
        "verdict": "partly shared",
        "shared": (
            "models.machines.virim.config.board_of",
            "models.machines.virim.config.buffers_of",
        ),
        "txn": "per board, image rows through a SimPy resampler and a row store, each "
        "row's samples spread over the ray casters (VirimTransaction.run)",
        "cycle": "per board, ray by ray through the resampler, ray buffers and the "
        "earliest free ray caster (config.board_schedule)",
    },
)
