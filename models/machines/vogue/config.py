"""VOGUE's parameters: the ``[buffers]`` model (ring bandwidth, ray set-up) and its rules.

# Ref: the overview (shared/docs/reference/000_d6a752d96745b32a.txt, "Special-purpose
#      rendering hardware") [V]: VOGUE [116], a modular add-on accelerator; for each pixel
#      the host defines a ray and sends it to the accelerator; a module processes the
#      complete ray, at evenly spaced resampling locations, and returns the pixel's colour
#      to the host; several modules combine; 512^3 at 20 projections/s would need 64
#      boards and a 5.2 GB/s ring-connected cubic network.  Everything below is [I].

The model (docs/early-machines.md, "VOGUE"): ``pipeline.count`` boards of one module
each, one sample per clock per module; the volume is spread over the boards in z-slabs
and circulates on a unidirectional ring once a frame so that every module sees every
voxel (the ring's load is the volume's bytes on each link) [I]; the host hands each ray
to the module that will be free first [I].
"""

from __future__ import annotations

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, between, integer, validate
from hwsim.spec.arch import ArchConfig
from models.frame import Frame
from models.machines.common.sections import refuse_sections

__all__ = ["VogueBuffers", "check_frame", "parse_buffers", "ring_link_bytes", "voxel_bytes"]


class VogueBuffers(Schema):
    """``[buffers]``: the ring's bandwidth per link (bytes/s) and the clocks a module
    spends taking a host-defined ray (origin, increment, count) before its first sample."""

    ring_bytes_per_second: between(1e3, 1e13) = 1e9
    ray_setup_cycles: integer(0, 1 << 16) = 4


def parse_buffers(arch: ArchConfig) -> VogueBuffers:
    """``arch.buffers`` as :class:`VogueBuffers` (checked when the file was loaded)."""
    return validate(arch.buffers, VogueBuffers, arch.source, prefix="buffers")


def check_frame(frame: Frame) -> None:
    """Refuse what VOGUE's modules cannot render: plans not cast from the image plane
    (every rung of the machine asks here)."""
    refuse_sections(frame.arch, "VOGUE")
    if frame.plan.kind != "ray":
        raise InputError(
            "VOGUE casts host-defined rays at evenly spaced locations",
            source=frame.arch.source,
            key="pipeline.order",
            allowed="ray",
        )


def voxel_bytes(frame: Frame) -> int:
    """Bytes of one voxel on the ring (the datapath's voxel width, whole bytes)."""
    return -(-frame.datapath.voxel_bits // 8)


def slab_bytes(frame: Frame, boards: int) -> np.ndarray:
    """Bytes of the z-slab each board holds (near-equal slabs of whole voxel slices)."""
    nz, ny, nx = frame.volume.shape
    edges = (np.arange(boards + 1) * nz) // boards
    return np.diff(edges) * ny * nx * voxel_bytes(frame)


def ring_link_bytes(frame: Frame, boards: int) -> np.ndarray:
    """Bytes each ring link (board ``k`` to ``k + 1``) carries a frame: every slab travels
    from its board past every other board, so link ``k`` carries all slabs but the one
    of board ``k + 1`` (nothing with one board)."""
    slabs = slab_bytes(frame, boards)
    if boards == 1:
        return np.zeros(1, np.int64)
    return (slabs.sum() - np.roll(slabs, -1)).astype(np.int64)
