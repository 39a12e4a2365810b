"""Texture-slicing graphics hardware (``shear-image`` 2-D stacks, ``ray`` 3-D textures)
as a :class:`Machine`.

# Ref: docs/architectures.md ("texture-slicer").
"""

from __future__ import annotations

from models.machines import Machine, single_frames
from models.machines.texslicer.config import TexBuffers, check_arch
from models.machines.texslicer.cycle import TexSlicer
from models.machines.texslicer.transaction import TexSlicerTransaction

MACHINE = Machine(
    name="texslicer",
    orders=("ray", "shear-image"),
    cycle=single_frames(TexSlicer),
    transaction=TexSlicerTransaction,
    package="models.machines.texslicer",
    buffers=TexBuffers,
    check_arch=check_arch,
    independence={
        "verdict": "shared",
        "shared": (
            "models.machines.texslicer.texture.TexelLines",
            "models.machines.texslicer.cycle.frame_params",
            "models.machines.texslicer.cycle.tile_loads",
        ),
        "txn": "a SimPy process per slice playing its tiles' raster and memory activities "
        "(TexSlicerTransaction.run)",
        "cycle": "the larger of each tile's raster and memory clocks, summed (TexSlicer.run)",
    },
)
