"""Where the 3-D cursor is, and its float64 blend: the reference the cursor unit matches.

# Ref: architectures.md section 3 (VolumePro 500 hardware cursor, [V] vli.h VLICursor);
#      the scene table: hwsim/spec/scene_cursor.py; fixed point: models/units/cursor.py.

A sample at voxel index position ``p`` lies on the cursor's axis-``k`` part when, with
``d = p - position`` and the half-open band ``-w/2 <= d < w/2`` (``w`` the width, so a
band holds ``w`` voxel centres)::

    crosshair  d on both other axes in the band, and |d_k| <= length/2 (length 0: any)
    plane      d_k in the band, and |d| <= length/2 on both other axes (length 0: any)

A sample on several parts takes the first enabled one in x, y, z order [I]; with
``exclude_overlap`` it shows no cursor [I: vli.h kExcludeOverlap].  The cursor is drawn
into the sample stream after shading and before opacity correction [I: the published
papers do not place it]: ``rgb = a_c c + (1 - a_c) rgb``, ``alpha = a_c + (1 - a_c)
alpha``, so an opaque cursor replaces the sample and a transparent sample on it takes
the cursor's opacity.  It is not lit.
"""

from __future__ import annotations

import numpy as np

from hwsim.spec.scene_cursor import CursorSpec

__all__ = ["cursor_parts", "blend_cursor"]

#: ``cursor_parts`` value of a sample off the cursor.
OFF = -1


def cursor_parts(zyx: np.ndarray, cursor: CursorSpec) -> np.ndarray:
    """``(n,)`` int8: the axis (0 = x, 1 = y, 2 = z) of the cursor part each sample at
    index positions ``zyx`` ``(n, 3)`` lies on, ``-1`` where none."""
    zyx = np.asarray(zyx, dtype=np.float64)
    d = zyx[:, ::-1] - np.asarray(cursor.position, dtype=np.float64)  # (n, 3) x, y, z
    half = cursor.width / 2.0
    band = (d >= -half) & (d < half)
    within = np.abs(d) <= cursor.length / 2.0 if cursor.length > 0 else np.ones_like(band)
    hits = np.zeros(d.shape, dtype=bool)
    for k, axis in enumerate(cursor.axes):
        if not axis.enabled:
            continue
        others = [a for a in range(3) if a != k]
        if cursor.type == "crosshair":
            hits[:, k] = band[:, others].all(axis=1) & within[:, k]
        else:
            hits[:, k] = band[:, k] & within[:, others].all(axis=1)
    part = np.where(hits.any(axis=1), np.argmax(hits, axis=1), OFF).astype(np.int8)
    if cursor.exclude_overlap:
        part[hits.sum(axis=1) > 1] = OFF
    return part


def blend_cursor(
    rgb: np.ndarray, alpha: np.ndarray, part: np.ndarray, cursor: CursorSpec
) -> tuple[np.ndarray, np.ndarray]:
    """Float64 ``(rgb (n, 3), alpha (n,))`` with the cursor drawn over the samples whose
    ``part`` (:func:`cursor_parts`) is an axis."""
    rgb, alpha = np.array(rgb, dtype=np.float64), np.array(alpha, dtype=np.float64)
    for k, axis in enumerate(cursor.axes):
        on = part == k
        if on.any():
            a = axis.opacity
            rgb[on] = a * np.asarray(axis.color) + (1.0 - a) * rgb[on]
            alpha[on] = a + (1.0 - a) * alpha[on]
    return rgb, alpha
