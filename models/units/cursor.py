"""The 3-D cursor unit: VolumePro 500's hardware cursor drawn into the sample stream,
bit-exact in fixed point.

# Ref: architectures.md section 3 ([V] vli.h VLICursor: crosshair or plane, widths
#      1/3/5/7 voxels, per-axis colour and opacity, packed 0..255 as VLIRGBAPacked);
#      geometry and float64 blend: hwsim/golden/cursor.py.

Formats (``nearest-up`` = ``floor(x + 1/2)``)::

    cursor.rgba   unorm 8 per channel (the packed VLIRGBAPacked form), expanded to
                  UQ1.12 as the classifier expands its LUT entries (0 and 1.0 exact)
    out           UQ1.12 colour and opacity: one rounding of the exact convex
                  combination a_c c + (1 - a_c) x, so out <= 1.0 and a_c = 1.0
                  replaces the sample exactly

Which samples lie on the cursor is the golden decision (:func:`cursor_parts`) on the
plan's positions: comparators against the host's bounds, no arithmetic to round.  Error
against the float64 blend of the same samples: the 8-bit quantisation of colour and
opacity (<= 2**-9 each) plus one UQ1.12 rounding (2**-13).
"""

from __future__ import annotations

import numpy as np

from hwsim.golden.cursor import cursor_parts
from hwsim.numerics import round_shift, uq
from hwsim.spec.scene_cursor import CursorSpec
from models.units.classify import expand

__all__ = ["II", "LATENCY", "RGBA", "CursorTable", "cursor_parts"]

#: Cycles added to the pipeline, [I] (not published): the comparators run beside the
#: shader and the one multiply-add per channel shares the opacity-correction stage.
LATENCY = 0
II = 1
RGBA_BITS = 8
RGBA = uq("cursor.rgba", RGBA_BITS, 0)
_F = 12


class CursorTable:
    """The cursor's per-axis colours and opacities as the host loads them (UQ1.12,
    from 8-bit packed values), and the blend."""

    def __init__(self, cursor: CursorSpec) -> None:
        self.cursor = cursor
        full = (1 << RGBA_BITS) - 1
        packed = np.array([[*axis.color, axis.opacity] for axis in cursor.axes], dtype=np.float64)
        #: ``(3, 4)`` int64 UQ1.12: rows x, y, z; columns r, g, b, a.
        self.rgba = expand(np.floor(packed * full + 0.5).astype(np.int64), RGBA_BITS)

    def parts(self, zyx: np.ndarray) -> np.ndarray:
        """The cursor part of each sample (:func:`cursor_parts`)."""
        return cursor_parts(zyx, self.cursor)

    def blend(
        self, rgb: np.ndarray, alpha: np.ndarray, part: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """UQ1.12 ``(rgb (n, 3), alpha (n,))`` with the cursor drawn over samples on it."""
        on = part >= 0
        rgb, alpha = np.array(rgb, dtype=np.int64), np.array(alpha, dtype=np.int64)
        if not on.any():
            return rgb, alpha
        c = self.rgba[part[on]]  # (m, 4)
        a = c[:, 3:4]
        x = np.concatenate([rgb[on], alpha[on, None]], axis=1)
        top = np.concatenate([c[:, :3], np.full_like(a, 1 << _F)], axis=1)
        out = round_shift(a * top + ((1 << _F) - a) * x, _F, "nearest-up")
        rgb[on], alpha[on] = out[:, :3], out[:, 3]
        return rgb, alpha
