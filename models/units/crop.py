"""Cropping and thick cut planes.

# Ref: architectures.md section 3 (VolumePro 500: box cropping; one oblique cut plane
#      with thickness and fall-off, VLICutPlane(A, B, C, D, thickness, falloff)).

The crop box compares sample positions with inclusive index limits: comparators, exact,
shared with the golden renderer (``hwsim.golden.shading.crop_keep``).  The cut plane
works in fixed point: positions in world units with 8 fraction bits, the normal SQ1.12,
the signed distance with 20 fraction bits; the factor is UQ1.12::

    beyond = |n.p - offset| - thickness / 2
    factor = 1 if beyond <= 0 else max(0, 1 - beyond / falloff)   (0 if falloff == 0)

Error against float64: the normal's quantisation moves the distance by up to
``2**-13 * sqrt(3) * |p|``, the position's by ``2**-9 * sqrt(3)``; divided by the
fall-off and plus ``2**-13`` of rounding.
"""

from __future__ import annotations

import numpy as np

from hwsim.golden.shading import crop_keep
from hwsim.scene import CutPlane

__all__ = ["crop_keep", "cut_factor", "LATENCY", "II"]

LATENCY = 1  # cycles, [I] (comparators and one multiply-add)
II = 1
ONE = 1 << 12


def cut_factor(p_world: np.ndarray, planes: tuple[CutPlane, ...]) -> np.ndarray:
    """UQ1.12 opacity factor of world points ``(n, 3)`` (x, y, z) for thick cut planes."""
    p = np.floor(np.asarray(p_world, dtype=np.float64) * 256 + 0.5).astype(np.int64)
    factor = np.full(p.shape[0], ONE, dtype=np.int64)
    for plane in planes:
        normal = np.asarray(plane.normal, dtype=np.float64)
        normal = np.floor(normal / np.linalg.norm(normal) * ONE + 0.5).astype(np.int64)
        dist = p @ normal - int(np.floor(plane.offset * (1 << 20) + 0.5))
        beyond = np.abs(dist) - int(np.floor(plane.thickness / 2 * (1 << 20) + 0.5))
        falloff = int(np.floor(plane.falloff * (1 << 20) + 0.5))
        if falloff > 0:
            f = ONE - (2 * np.maximum(beyond, 0) * ONE + falloff) // (2 * falloff)
            f = np.clip(f, 0, ONE)
        else:
            f = np.where(beyond <= 0, ONE, 0)
        f = ONE - f if plane.invert else f
        factor = (factor * f + ONE // 2) >> 12
    return factor
