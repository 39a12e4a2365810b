"""Empty-space leaping of ideal-ray plans, compiled: :meth:`SamplePlan.leap`'s march
one ray at a time, the same float64 operations, the same step ranges.

# Ref: Levoy, "Efficient Ray Tracing of Volume Data", ACM TOG 1990 (empty-space
#      skipping by distance); hwsim.golden.occupancy (the distance field).

:meth:`~hwsim.golden.positions.SamplePlan.leap` marches every ray from each end past
blocks the occupancy marks empty, in NumPy over the set of rays still marching.  For
``ray`` plans (the golden renderer's default, every frame of a rotation) that march is
serial NumPy and a third of a compiled golden frame; here each ray marches in compiled
code with the NumPy march's arithmetic: the position ``o + t d`` with ``t = (k_first +
k_dir j) dt``, ``numpy.floor_divide``'s rule for the block, the same skip and face
formulas, the same bounds.  ``tests/golden/test_leap_rays.py`` checks the step ranges are
the NumPy march's exactly.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["leap_ray_plan"]

_TINY = 1e-12


def leap_ray_plan(plan, occupancy) -> tuple[np.ndarray, np.ndarray]:
    """New ``(j_lo, j_hi)`` of a ``ray`` ``plan`` leapt past ``occupancy``'s empty blocks
    (rays left without samples have ``j_lo > j_hi``)."""
    d = plan._d.reshape(-1, 3)
    delta = np.broadcast_to(plan._delta, (plan.ray_ids.size, 3))
    reach = np.maximum(np.maximum(np.abs(delta[:, 0]), np.abs(delta[:, 1])), np.abs(delta[:, 2]))
    j_lo, j_hi = plan.j_lo.copy(), plan.j_hi.copy()
    _march(
        np.ascontiguousarray(plan._o),
        np.ascontiguousarray(d),
        int(plan.k_first),
        int(plan.k_dir),
        float(plan._dt),
        np.ascontiguousarray(np.reshape(plan._delta, (-1, 3))),
        np.ascontiguousarray(reach),
        plan.n - 1.0,
        int(occupancy.block),
        np.ascontiguousarray(occupancy.distance),
        j_lo,
        j_hi,
    )
    return j_lo, j_hi


@numba.njit(cache=True, nogil=True)
def _floor_divide(a, b):  # pragma: no cover - compiled
    """``numpy.floor_divide(a, b)`` for float64 (NumPy's ``npy_divmod``)."""
    mod = np.fmod(a, b)
    div = (a - mod) / b
    if mod != 0.0:
        if (b < 0) != (mod < 0):
            div -= 1.0
    if div != 0.0:
        floordiv = math.floor(div)
        if div - floordiv > 0.5:
            floordiv += 1.0
        return floordiv
    return math.copysign(0.0, a / b)


@numba.njit(cache=True, nogil=True)
def _march(
    o, d, k_first, k_dir, dt, delta, reach, top, block, distance, j_lo, j_hi
):  # pragma: no cover
    n_rays = o.shape[0]
    fblock = np.float64(block)
    # A power-of-two block: the quotient of a clipped (>= 0) position is exact, so its
    # floor is ``numpy.floor_divide``'s without the remainder (``fmod`` was half the march).
    exact = block > 0 and (block & (block - 1)) == 0
    blk = np.empty(3)
    p = np.empty(3)
    for sign in (1, -1):
        for r in range(n_rays):
            dr = 0 if d.shape[0] == 1 else r
            er = 0 if delta.shape[0] == 1 else r
            j = j_lo[r] if sign > 0 else j_hi[r]
            while True:
                t = (k_first + k_dir * j) * dt
                for a in range(3):
                    p[a] = o[r, a] + t * d[dr, a]
                    clipped = min(max(p[a], 0.0), top[a])
                    if exact:
                        blk[a] = math.floor(clipped / fblock)
                    else:
                        blk[a] = _floor_divide(clipped, fblock)
                c = distance[np.int64(blk[0]), np.int64(blk[1]), np.int64(blk[2])]
                if c <= 0:
                    break
                skip = math.floor(((c - 1) * block - 1e-6) / reach[r])
                along = np.inf
                for a in range(3):
                    step = sign * delta[er, a]
                    if abs(step) > _TINY:
                        if step > 0:
                            face = (blk[a] + 1) * block - p[a]
                        else:
                            face = p[a] - blk[a] * block
                        along = min(along, face / abs(step))
                skip = max(max(skip, math.ceil(along - 1e-6)), 1.0)
                j += sign * np.int64(skip)
                if not (j <= j_hi[r] and j >= j_lo[r]):
                    break
            if sign > 0:
                j_lo[r] = j
            else:
                j_hi[r] = j
