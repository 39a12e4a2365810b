"""The texture slicer's ``[buffers]`` table and its per-fragment costs.

# Ref: shared/docs/reference/000_d6a752d96745b32a.txt ("General-purpose rendering
#      hardware": 2-D texture stacks, one per major viewing direction, chosen per view,
#      with popping when the stack switches; 3-D textures sliced parallel to the screen;
#      a gradient volume loaded into texture memory for shading [V]).
#      docs/architectures.md ("texture-slicer"): the timing rules and what is inferred.

A fragment's texture work is counted in texture-unit clocks: a bilinear fetch from one
2-D slice costs one, a trilinear fetch from a 3-D texture two (half rate [R]), and a
post-classification lookup of the transfer function (a dependent texture read of a
small cached table) one.  A pixel pipeline has ``texture_units`` units, so a fragment
occupies its pipeline ``ceil(clocks / texture_units)`` clocks (at least one: the fill
rate).  Shading reads the gradient from the same RGBA texel as the value (normal in RGB,
density in A [I]): it adds bytes per texel, not fetches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, integer, validate
from hwsim.spec.arch import ArchConfig

__all__ = ["TexBuffers", "TexParams", "check_arch", "params_of"]

#: Clocks from a fragment's rasterization to its blend into the frame buffer [I].
LATENCY = 24
#: Frame-buffer bytes per blended fragment: RGBA8 read and written back [I].
BLEND_BYTES = 8


class TexBuffers(Schema):
    """``[buffers]`` of a texture slicer: how textures are held and fetched."""

    textures: Literal["2d", "3d"] = "3d"
    texture_units: integer(1, 8) = 2
    texture_line: tuple[integer(1, 64), integer(1, 64), integer(1, 64)] = (4, 4, 4)
    raster_tile: integer(1, 1 << 16) = 256
    memory_bytes_per_clock: integer(1, 1 << 12) = 32


@dataclass(frozen=True)
class TexParams:
    """The parsed table plus what a frame adds (texel bytes, clocks per fragment)."""

    buffers: TexBuffers
    texel_bytes: int
    fetch_clocks: int  # texture-unit clocks of one fragment
    fragment_clocks: int  # pipeline clocks of one fragment

    @property
    def line_bytes(self) -> int:
        lz, ly, lx = self.buffers.texture_line
        return lz * ly * lx * self.texel_bytes


def check_arch(arch: ArchConfig) -> None:
    """2-D stacks sample on the slice planes (``shear-image``); 3-D textures on
    view-aligned planes (``ray``)."""
    b = validate(arch.buffers, TexBuffers, arch.source, prefix="buffers")
    want = {"2d": "shear-image", "3d": "ray"}[b.textures]
    if arch.order != want:
        raise InputError(
            f"{arch.name}: {b.textures} textures are sampled in the {want} order",
            source=arch.source,
            key="pipeline.order",
            allowed=want,
        )


def params_of(arch: ArchConfig, *, lit: bool, post: bool, voxel_bytes: int) -> TexParams:
    """The frame's texture costs: RGBA texels (4 bytes) when lit, else the voxel's own
    bytes; one extra unit clock for a post-classification lookup."""
    b = validate(arch.buffers, TexBuffers, arch.source, prefix="buffers")
    fetch = (1 if b.textures == "2d" else 2) + (1 if post else 0)
    return TexParams(
        buffers=b,
        texel_bytes=4 if lit else voxel_bytes,
        fetch_clocks=fetch,
        fragment_clocks=max(1, -(-fetch // b.texture_units)),
    )
