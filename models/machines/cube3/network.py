"""Cube-3's volume memory read beam by beam and the barrel shifter that de-skews it.

# Ref: architectures.md 1.2 (a beam comes out of the skewed memory cyclically rotated; a
#      barrel shifter undoes it, Cube-3 [V]); models.machines.common.skewed (the memory).

A beam is up to ``n`` consecutive voxels of a row: each lies in a different module, so
the memory returns them on its ``n`` lanes in module order, the beam's first voxel on
lane ``(x0 + y0 + z0) mod n``.  The shifter rotates the lanes back by that amount (one
beam a clock) and the beam enters the 2D buffers in row order.
"""

from __future__ import annotations

import numpy as np

from models.machines.common.skewed import CubicFrameBuffer

__all__ = ["deliver_volume"]


def _beams(shape: tuple[int, int, int], kp: int, n: int) -> np.ndarray:
    """Voxel coordinates ``(beams, n, 3)`` zyx of every beam (rows along the fastest axis
    other than ``kp``, cut every ``n`` voxels; -1 past a row's end)."""
    row_axis = 2 if kp != 2 else 1
    length = shape[row_axis]
    cuts = -(-length // n)
    others = [ax for ax in range(3) if ax != row_axis]
    grid = np.indices([shape[others[0]], shape[others[1]], cuts]).reshape(3, -1).T
    beams = np.full((grid.shape[0], n, 3), -1, np.int64)
    offset = grid[:, 2:3] * n + np.arange(n)[None, :]
    valid = offset < length
    beams[..., others[0]] = grid[:, 0:1]
    beams[..., others[1]] = grid[:, 1:2]
    beams[..., row_axis] = offset
    beams[~valid] = -1
    return beams


def deliver_volume(
    memory: CubicFrameBuffer, kp: int, shifter_offset: int = 0
) -> tuple[np.ndarray, int, int]:
    """The volume as the shifter hands it to the 2D buffers, the beams read and the lanes
    rotated in all (``shifter_offset``: a faulty shifter's extra rotation)."""
    n, shape = memory.modules, memory.shape
    beams = _beams(shape, kp, n)
    valid = beams[..., 0] >= 0
    coords = beams[valid]
    lanes = np.zeros(beams.shape[:2], dtype=memory.words.dtype)
    module = np.zeros(beams.shape[:2], np.int64)
    module[valid] = memory.module_of(coords)
    lanes[np.nonzero(valid)[0], module[valid]] = memory.read(coords)  # memory's output lanes
    shift = (module[:, 0] + shifter_offset) % n  # the first voxel's lane
    rows = np.take_along_axis(lanes, (shift[:, None] + np.arange(n)[None, :]) % n, axis=1)
    delivered = np.zeros(shape, dtype=memory.words.dtype)
    delivered[tuple(coords.T)] = rows[valid]
    return delivered, int(beams.shape[0]), int(shift.sum())
