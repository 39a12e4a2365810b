"""Empty-space leaping: which blocks of the volume can produce a visible sample.

# Ref: Levoy, "Efficient Ray Tracing of Volume Data", ACM TOG 1990 (hierarchical
#      empty-space skipping); Lacroute & Levoy, SIGGRAPH 1994 (skipping transparent runs).

The volume is cut into cubes of ``block`` voxels per index axis ``(z, y, x)``.  A sample
at index position ``p`` (clamped to ``[0, n - 1]``, as the filters clamp) lies in block
``floor(p / block)``, and a trilinear or nearest sample there is a convex combination of
voxels in that block and the next one along each axis.  Its value therefore lies in the
interval ``[lo, hi]`` of those 2 x 2 x 2 blocks, and a block is *occupied* when the
quantity that decides visibility can be non-zero somewhere on that interval:

* composite: the transfer function's opacity (piecewise linear, so its maximum on
  ``[lo, hi]`` is at an end or at a control point inside).  Pre-classification,
  gradient modulation, cut planes and crop only lower opacity, so they are covered;
* iso: ``hi >= iso_value``.

:class:`Occupancy` holds the chessboard distance (in blocks) from every block to the
nearest occupied one.  A ray at ``p`` in a block at distance ``c >= 1`` can move
``(c - 1) * block`` index units (max-norm) without meeting an occupied block, so the
sample plans shorten each ray's step range from both ends (:meth:`SamplePlan.leap`).
Skipped samples would have had opacity exactly 0 (or a value below the iso threshold),
so the image is bit-identical with and without leaping.  Cubic filters overshoot the
voxel range and are never leapt.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["Occupancy", "block_ranges", "opacity_can_be_positive", "occupancy_from_ranges"]

#: Block edge in voxels: small enough to hug a skin surface, large enough that the
#: distance field (n / block)^3 is tiny next to the volume.
BLOCK = 4


@dataclass(frozen=True)
class Occupancy:
    """Chessboard distance in blocks to the nearest occupied block.

    ``distance`` is int64 ``(nbz, nby, nbx)``; 0 marks an occupied block.  ``empty`` is
    True when no block is occupied (no ray takes a sample).
    """

    block: int
    distance: np.ndarray
    empty: bool

    def distance_at(self, zyx: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
        """Distance of the block holding each position ``(n, 3)`` (clamped to the volume)."""
        hi = np.asarray(shape, dtype=np.float64) - 1.0
        return self.distance_of(np.clip(zyx, 0.0, hi) // self.block)

    def distance_of(self, block: np.ndarray) -> np.ndarray:
        """Distance of blocks given by their (float or int) indices ``(n, 3)``."""
        b = block.astype(np.int64)
        nb = self.distance.shape
        return self.distance.ravel()[(b[:, 0] * nb[1] + b[:, 1]) * nb[2] + b[:, 2]]


def block_ranges(data: np.ndarray, block: int = BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """Min and max value over each block and its ``+1`` neighbours along every axis.

    Returns float64 arrays ``(ceil(nz/b), ceil(ny/b), ceil(nx/b))``.  Edge blocks are
    padded by repeating the edge voxels (clamp to edge, as the filters do).
    """
    pad = [(0, -n % block) for n in data.shape]
    padded = np.pad(data, pad, mode="edge") if any(p[1] for p in pad) else data
    nb = [s // block for s in padded.shape]
    cubes = padded.reshape(nb[0], block, nb[1], block, nb[2], block)
    lo = cubes.min(axis=(1, 3, 5)).astype(np.float64)
    hi = cubes.max(axis=(1, 3, 5)).astype(np.float64)
    for axis in range(3):
        nxt = [slice(None)] * 3
        nxt[axis] = slice(1, None)
        here = [slice(None)] * 3
        here[axis] = slice(0, -1)
        lo[tuple(here)] = np.minimum(lo[tuple(here)], lo[tuple(nxt)])
        hi[tuple(here)] = np.maximum(hi[tuple(here)], hi[tuple(nxt)])
    return lo, hi


def opacity_can_be_positive(
    lo: np.ndarray, hi: np.ndarray, values: np.ndarray, alpha: np.ndarray
) -> np.ndarray:
    """Whether the piecewise-linear opacity ``(values, alpha)`` (clamped at its ends, as
    ``numpy.interp``) is positive anywhere on ``[lo, hi]``, elementwise."""
    positive = np.interp(lo, values, alpha) > 0
    positive |= np.interp(hi, values, alpha) > 0
    knots = np.sort(values[alpha > 0])
    if knots.size:
        first = np.searchsorted(knots, lo, side="left")
        inside = first < knots.size
        positive[inside] |= knots[first[inside]] <= hi[inside]
    return positive


def occupancy_from_ranges(occupied: np.ndarray, block: int = BLOCK) -> Occupancy:
    """Distance field of a boolean block grid (True = may hold a visible sample)."""
    if not occupied.any():
        return Occupancy(block, np.full(occupied.shape, np.iinfo(np.int64).max // 4), True)
    if occupied.all():
        return Occupancy(block, np.zeros(occupied.shape, dtype=np.int64), False)
    distance = ndimage.distance_transform_cdt(~occupied, metric="chessboard")
    return Occupancy(block, distance.astype(np.int64), False)
