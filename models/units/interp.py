"""Trilinear interpolation in fixed point.

# Ref: architectures.md sections 1.3, 6.4 and 9.1 (TriLin; weights constant per slice in
#      parallel projection); Lacroute & Levoy 1994.

Positions follow the golden renderer (clamp to ``[0, n - 1]``; ``i0 = min(floor(p),
n - 2)``).  The fraction ``f = p - i0`` is quantised to ``weight_bits`` (format
``interp.weight``, UQ1.W: 1.0 is representable).  Voxels are promoted by ``S =
sample_frac_bits`` and combined by seven lerps, x first, then y, then z::

    lerp(a, b, f) = a + round((b - a) f / 2**W)        (rounding: ``rounding``)

The result carries ``in_frac_bits + S`` fraction bits.  In parallel projection every
sample of a slice has the same fractional offsets, so the weights are constant per
slice by construction (the plan guarantees it).

Error bound against float64 trilinear interpolation of the same voxels, in voxel units:
``3 * (D * 2**-(W+1) + 2**-(S+1))``, with ``D`` the largest difference between the
voxels of the cell (each axis: weight error times the local difference plus one
rounding; lerps are convex, so errors do not grow).  Property-tested.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.numerics import FixedFormat, round_shift

__all__ = [
    "InterpConfig",
    "InterpTaps",
    "interp_taps",
    "axis_cells",
    "corner_offsets",
    "interpolate",
    "lerp_corners",
    "lerp",
    "bilinear",
    "error_bound",
    "LATENCY",
    "II",
]

LATENCY = 4  # cycles, [I] architectures.md 9.3 (TriLin 3-4)
II = 1


@dataclass(frozen=True, kw_only=True)
class InterpConfig:
    """Widths of the interpolator (defaults: VolumePro 500, [I])."""

    weight_bits: int = 8
    sample_frac_bits: int = 4
    rounding: str = "nearest-up"

    def __post_init__(self) -> None:
        if not 1 <= self.weight_bits <= 16 or not 1 <= self.sample_frac_bits <= 12:
            raise ValueError("interp widths: weight_bits 1..16, sample_frac_bits 1..12")

    @property
    def weight(self) -> FixedFormat:
        return FixedFormat(
            name="interp.weight",
            signed=False,
            int_bits=1,
            frac_bits=self.weight_bits,
            rounding=self.rounding,
        )


@dataclass(frozen=True)
class InterpTaps:
    """``idx (8, n)`` flat voxel indices, corner ``c = 4 dz + 2 dy + dx``; ``frac (3, n)``
    raw UQ1.W fractions along ``(z, y, x)``."""

    idx: np.ndarray
    frac: np.ndarray


def axis_cells(
    p: np.ndarray, hi: float | np.ndarray, cfg: InterpConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Cell index ``i0 = min(floor(p), n - 2)`` (``p`` clamped to ``[0, n - 1]``, ``hi =
    n - 1``; ``i0 = 0`` when ``n = 1``) and the quantised UQ1.W fraction ``p - i0``.

    ``p`` is one axis's coordinates with scalar ``hi``, or ``(3, n)`` with ``hi`` of shape
    ``(3, 1)``.  Returns int64 ``i0`` and raw fractions, both shaped like ``p``.
    """
    p = np.clip(p, 0.0, hi)
    i0 = np.minimum(np.floor(p), np.maximum(np.subtract(hi, 1.0), 0.0))
    return i0.astype(np.int64), cfg.weight.quantize(p - i0)


def corner_offsets(shape: tuple[int, int, int]) -> np.ndarray:
    """Flat-index offsets ``(8,)`` of a cell's corners ``c = 4 dz + 2 dy + dx`` from its
    low corner (0 along an axis of one voxel, where ``i0 + 1`` clamps to ``i0``)."""
    ny, nx = shape[1], shape[2]
    dz, dy, dx = (s if n > 1 else 0 for s, n in zip((ny * nx, nx, 1), shape, strict=True))
    c = np.arange(8)
    return ((c >> 2) & 1) * dz + ((c >> 1) & 1) * dy + (c & 1) * dx


def interp_taps(zyx: np.ndarray, shape: tuple[int, int, int], cfg: InterpConfig) -> InterpTaps:
    """Voxel indices and quantised weights of the cells holding positions ``zyx (n, 3)``."""
    # One clip / floor / quantise over all three axes, then the low corner's flat index
    # plus constant corner offsets.
    hi = np.asarray(shape, dtype=np.float64)[:, None] - 1.0
    i0, frac = axis_cells(zyx.T, hi, cfg)
    base = (i0[0] * shape[1] + i0[1]) * shape[2] + i0[2]
    return InterpTaps(base + corner_offsets(shape)[:, None], frac)


def interpolate(
    flat: np.ndarray, t: InterpTaps, cfg: InterpConfig, in_frac_bits: int = 0
) -> np.ndarray:
    """Interpolate a raveled raw array (any sign) at the taps: ``(n,)`` int64 with
    ``in_frac_bits + sample_frac_bits`` fraction bits."""
    v = np.take(flat, t.idx).astype(np.int64, copy=False) << cfg.sample_frac_bits
    return lerp_corners(v, t.frac, cfg)


def lerp_corners(v: np.ndarray, frac: np.ndarray, cfg: InterpConfig) -> np.ndarray:
    """The seven lerps of promoted corners ``v (8, n)`` (``c = 4 dz + 2 dy + dx``) with
    raw fractions ``frac (3, n)`` along ``(z, y, x)``: x first (four lerps at once), then
    y (two), then z."""
    fz, fy, fx = frac
    x = lerp(v[0::2], v[1::2], fx, cfg)  # corners (dz, dy) = 00, 01, 10, 11
    y = lerp(x[0::2], x[1::2], fy, cfg)  # dz = 0, 1
    return lerp(y[0], y[1], fz, cfg)


def lerp(a: np.ndarray, b: np.ndarray, f: np.ndarray, cfg: InterpConfig) -> np.ndarray:
    """One linear interpolation step: ``a + round((b - a) f / 2**W)`` (``f`` raw UQ1.W)."""
    return a + round_shift((b - a) * f, cfg.weight_bits, cfg.rounding)


def bilinear(v00, v01, v10, v11, fa, fb, cfg: InterpConfig) -> np.ndarray:
    """In-slice interpolation of promoted corners: along ``b`` first, then ``a``.

    ``v<i><j>`` is the corner ``(a0 + i, b0 + j)``.  With ``b`` the faster-varying in-slice
    axis this is exactly :func:`interpolate` of a sample lying on a voxel slice (the
    principal-axis weight 0 or 1 selects one slice exactly), the lerp order x, y, z.
    """
    return lerp(lerp(v00, v01, fb, cfg), lerp(v10, v11, fb, cfg), fa, cfg)


def error_bound(max_difference: float, cfg: InterpConfig) -> float:
    """Worst-case |fixed - float| in input units for a cell whose voxels differ by at most
    ``max_difference``."""
    return 3 * (max_difference * 2.0 ** -(cfg.weight_bits + 1) + 2.0 ** -(cfg.sample_frac_bits + 1))
