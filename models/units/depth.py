"""Embedded geometry in fixed point: the 24-bit depth buffer, the per-sample depth test and
the geometry colour composited behind the volume.

# Ref: architectures.md section 4 (VolumePro 1000: image + 24-bit depth buffers, max
#      0x00FFFFFF, depth tests <, <=, =, >=, >, !=; vli.h); float64 counterpart:
#      hwsim/golden/geometry.py (depth metric, rasterisation).

Formats (``nearest-up`` = ``floor(x + 1/2)``)::

    depth.z         unorm 24: normalised depth d in [0, 1] -> round(d (2**24 - 1));
                    0xFFFFFF = far (a cleared buffer, no geometry)
    geometry.color  unorm 12 per channel (RGBA12 image buffer), expanded to the
                    compositor's UQ1.12 as the classifier does (0 and 1.0 exact)

The sample depth is the plan's float64 depth of the sample quantised the same way, so
the test compares two ``depth.z`` integers exactly.  Against the float test a sample can
flip only when its depth and the pixel's lie within one ``depth.z`` LSB (``2**-24`` of
the bounding-sphere diameter).  The blend is the compositor's front-to-back step with
the geometry as the last sample: ``w = round((1 - A) a)``, ``C += round(w c)``.
"""

from __future__ import annotations

import numpy as np

from hwsim.golden.geometry import TEST_OPERATORS, GeometryBuffers
from hwsim.numerics import uq
from models.units import composite as composite_unit
from models.units.classify import expand

__all__ = ["DEPTH", "COLOR", "LATENCY", "II", "quantise_depth", "quantise_color", "passes", "blend"]

#: One compare per sample, folded into the crop/cut mask stage ([I]).
LATENCY = 1
II = 1
DEPTH_BITS = 24
COLOR_BITS = 12
DEPTH = uq("depth.z", DEPTH_BITS, 0)
COLOR = uq("geometry.color", COLOR_BITS, 0)
FAR = (1 << DEPTH_BITS) - 1


def quantise_depth(depth: np.ndarray) -> np.ndarray:
    """Normalised depths in ``[0, 1]`` to ``depth.z`` integers (nearest-up)."""
    d = np.clip(np.asarray(depth, dtype=np.float64), 0.0, 1.0)
    return np.floor(d * FAR + 0.5).astype(np.int64)


def quantise_color(rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Geometry colour ``(n, 4)`` in ``[0, 1]`` to UQ1.12 ``(rgb (n, 3), alpha (n,))``
    through the ``geometry.color`` buffer."""
    top = (1 << COLOR_BITS) - 1
    q = np.floor(np.asarray(rgba, dtype=np.float64) * top + 0.5).astype(np.int64)
    q12 = expand(q, COLOR_BITS)
    return q12[:, :3], q12[:, 3]


def passes(test: str, sample_z: np.ndarray, pixel_z: np.ndarray) -> np.ndarray:
    """Depth test on ``depth.z`` integers: keep samples where ``sample <test> pixel``."""
    return TEST_OPERATORS[test](np.asarray(sample_z, np.int64), np.asarray(pixel_z, np.int64))


class DepthBuffers:
    """The quantised image + depth buffers of one frame (host-written, per image pixel)."""

    def __init__(self, buffers: GeometryBuffers) -> None:
        self.z = quantise_depth(buffers.depth)
        self.rgb, self.alpha = quantise_color(buffers.rgba)


def blend(acc: np.ndarray, buffers: DepthBuffers, cfg: composite_unit.CompositeConfig) -> None:
    """Composite every pixel's geometry colour behind its accumulator (UQ1.F), in place."""
    rays = np.flatnonzero(buffers.alpha > 0)
    if rays.size:
        composite_unit.front_to_back(acc, rays, buffers.rgb[rays], buffers.alpha[rays], cfg)
