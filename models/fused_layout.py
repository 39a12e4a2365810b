"""The functional rung's kernel voxels: a volume's raw voxels (and voxel differences)
laid out and narrowed for :class:`models.fused.CompositeKernel`, kept per volume.

# Ref: docs/fidelity.md ("How the functional rung simulates fast, exactly").
"""

from __future__ import annotations

import weakref

import numpy as np

from models.units import gradient as gradient_unit

__all__ = ["kernel_voxels"]


def _laid_out(a: np.ndarray, shape, order: tuple[int, int, int]) -> np.ndarray:
    """Flat ``a`` (a ``(z, y, x)`` volume of ``shape``) with its axes in memory ``order``
    (slowest first)."""
    a = np.asarray(a).reshape(shape)
    return (a if order == (0, 1, 2) else a.transpose(order)).ravel()


def _strides(shape, order: tuple[int, int, int]) -> np.ndarray:
    """Element strides of the z, y, x axes of a ``shape`` volume laid out in ``order``."""
    strides = np.zeros(3, dtype=np.int64)
    step = 1
    for axis in reversed(order):
        strides[axis] = step
        step *= shape[axis]
    return strides


def _narrowest(a: np.ndarray) -> np.ndarray:
    """``a`` in the narrowest of uint8, uint16, int16, int32, int64 holding its values."""
    lo, hi = (int(a.min()), int(a.max())) if a.size else (0, 0)
    for dtype in (np.uint8, np.uint16, np.int16, np.int32):
        info = np.iinfo(dtype)
        if info.min <= lo and hi <= info.max:
            return a.astype(dtype)
    return a.astype(np.int64)


#: Per-volume voxels (and voxel differences) in the kernel's layouts, by datapath voxel
#: width and memory order; dropped with the volume.
_DERIVED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def kernel_voxels(be, voxel_diffs: bool):
    """``(vox, shape, strides, offsets, dxyz)`` of back end ``be``'s volume for the
    kernel: the raw voxels flat in their layout, the volume's shape and the z, y, x
    element strides (int64), the eight corner offsets of a cell
    (``interp.corner_offsets`` in this layout) and the x, y, z voxel differences
    (``voxel_diffs``: the gradient comes from voxels; otherwise three one-voxel
    placeholders)."""
    dp = be.dp
    # The raw voxels (and differences) in their narrowest integer type, promoted as
    # they are read: a quarter of the promoted int64 bytes, half of int32 (memory
    # traffic is what a 256^3 frame waits on).
    # Laid out with the principal axis slowest: a step's samples lie on one voxel
    # slice, read from contiguous rows instead of one cache line each (x principal).
    shape = be.volume.shape
    axis = be.plan.principal_axis
    order = (2, 0, 1) if axis == 2 else (0, 1, 2)
    # Kept per volume (as the golden renderer keeps its derived arrays): successive
    # frames of one volume and datapath width lay the voxels out once per order.
    derived = _DERIVED.setdefault(be.volume, {})
    key = (dp.voxel_bits, order)
    if key not in derived:
        derived[key] = _narrowest(_laid_out(be.raw, shape, order))
    vox = derived[key]
    strides = _strides(shape, order)
    dz, dy, dx = (int(st) if n > 1 else 0 for st, n in zip(strides, shape, strict=True))
    offsets = np.array(
        [0, dx, dy, dx + dy, dz, dz + dx, dz + dy, dz + dy + dx], dtype=np.int64
    )  # interp.corner_offsets in this layout
    if not voxel_diffs:
        dxyz = (vox[:1],) * 3
    else:
        key = (dp.voxel_bits, order, "differences")
        if key not in derived:
            # One axis at a time, narrowed before it is laid out: a 512^3 volume
            # never holds three wide (int32) difference volumes at once.
            diffs = [
                _laid_out(_narrowest(gradient_unit.voxel_difference(be.raw, axis)), shape, order)
                for axis in (2, 1, 0)
            ]
            wide = np.result_type(*diffs)
            derived[key] = tuple(d.astype(wide, copy=False) for d in diffs)
        dxyz = derived[key]
    return vox, np.asarray(shape, dtype=np.int64), strides, offsets, dxyz
