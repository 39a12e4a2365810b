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
``3 * (D * 2**-(W+1) + 2**-(S+1))`` for the nearest roundings, twice that for the
directed ones (floor, truncate), with ``D`` the largest difference between the voxels of
the cell (each axis: weight error times the local difference plus one rounding; lerps
are convex, so errors do not grow).  Property-tested in tests/units/test_interp.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.numerics import ROUNDING_CODES, FixedFormat, round_scaled, round_shift_raw, uq

__all__ = [
    "InterpConfig",
    "InterpTaps",
    "interp_taps",
    "axis_cells",
    "corner_offsets",
    "interpolate",
    "lerp_corners",
    "lerp_plan",
    "promote",
    "promote_raw",
    "lerp",
    "lerp_raw",
    "cell_weight",
    "bilinear_raw",
    "bilinear",
    "error_bound",
    "LATENCY",
    "II",
]

#: Cycles: the RTL's stage plan (rtl/interp.py STAGES): each lerp as a product stage and
#: a sum stage, so every stage meets a 125 MHz clock at 0.35 um by the project's depth
#: estimate (issue 34).  architectures.md 9.3's "TriLin 3-4" [I] was one lerp per stage
#: (~50 gates deep, ~106 MHz).
LATENCY = 7
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
        return uq("interp.weight", 1, self.weight_bits, rounding=self.rounding)


class InterpTaps:
    """Cells and weights of ``n`` samples: ``idx (8, n)`` flat voxel indices, corner
    ``c = 4 dz + 2 dy + dx``; ``frac (3, n)`` raw UQ1.W fractions along ``(z, y, x)``.

    Built either from explicit ``idx`` or, by :func:`interp_taps`, from the low corner's
    index ``base (n,)`` and constant corner ``offsets (8,)`` (``idx`` is then formed only
    if asked for; :func:`interpolate` gathers just the corners it needs).
    """

    def __init__(
        self,
        idx: np.ndarray | None,
        frac: np.ndarray,
        *,
        base: np.ndarray | None = None,
        offsets: np.ndarray | None = None,
        cells: np.ndarray | None = None,
    ) -> None:
        if idx is None and (base is None or offsets is None):
            raise ValueError("InterpTaps needs idx, or base and offsets")
        self._idx, self.frac, self.base, self.offsets = idx, frac, base, offsets
        self.cells = cells  # (3, n) low-corner indices along (z, y, x), when known

    @property
    def idx(self) -> np.ndarray:
        if self._idx is None:
            self._idx = self.base + self.offsets[:, None]
        return self._idx

    def rows(self, corners: list[int]) -> np.ndarray:
        """Flat indices ``(len(corners), n)`` of the listed corners."""
        if self._idx is None:
            return self.base + self.offsets[corners, None]
        return self._idx[corners]

    def subset(self, sel: np.ndarray) -> InterpTaps:
        """The taps of samples ``sel`` (index array)."""
        cells = None if self.cells is None else np.take(self.cells, sel, axis=1)
        frac = np.take(self.frac, sel, axis=1)
        if self._idx is None:
            return InterpTaps(None, frac, base=self.base[sel], offsets=self.offsets, cells=cells)
        return InterpTaps(np.take(self._idx, sel, axis=1), frac, cells=cells)


def axis_cells(
    p: np.ndarray, hi: float | np.ndarray, cfg: InterpConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Cell index ``i0 = min(floor(p), n - 2)`` (``p`` clamped to ``[0, n - 1]``, ``hi =
    n - 1``; ``i0 = 0`` when ``n = 1``) and the quantised UQ1.W fraction ``p - i0``.

    ``p`` is one axis's coordinates with scalar ``hi``, or ``(3, n)`` with ``hi`` of shape
    ``(3, 1)``.  Returns int64 ``i0`` and raw fractions, both shaped like ``p``.
    NaN or Inf positions raise ``ValueError`` (as ``interp.weight``'s quantiser does).
    """
    p = np.asarray(p, dtype=np.float64)
    if p.size and not np.isfinite(p.min() + p.max()):
        raise ValueError("interp.weight: NaN or Inf cannot be quantised")
    i0, frac = cell_weight(p, hi, cfg.weight_bits, ROUNDING_CODES[cfg.rounding])
    return i0.astype(np.int64), frac.astype(np.int64)


def cell_weight(p, hi, weight_bits: int, code: int):
    """The arithmetic of :func:`axis_cells` on float arrays or scalars (compiled kernels
    call it too): ``(i0, raw fraction)`` as integral floats.  The fraction ``p - i0`` lies
    in ``[0, 1]``, so its UQ1.W quantisation never leaves the format."""
    p = np.minimum(np.maximum(p, 0.0), hi)
    i0 = np.minimum(np.floor(p), np.maximum(hi - 1.0, 0.0))
    return i0, round_scaled((p - i0) * 2.0**weight_bits, code)


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
    i0, frac = axis_cells(np.ascontiguousarray(zyx.T), hi, cfg)  # rows contiguous
    base = (i0[0] * shape[1] + i0[1]) * shape[2] + i0[2]
    return InterpTaps(None, frac, base=base, offsets=corner_offsets(shape), cells=i0)


def promote(flat: np.ndarray, cfg: InterpConfig) -> np.ndarray:
    """``flat << sample_frac_bits`` (the interpolator's input promotion) in the narrowest
    integer type in which every lerp of it is exact: int32 when ``(2 M + 1) 2**W < 2**31``
    for ``M`` the largest promoted magnitude (``(b - a) f`` plus the rounding addend),
    else int64.  Interpolating the promoted array gives the same integers either way."""
    flat = np.asarray(flat)
    lo, hi = (int(flat.min()), int(flat.max())) if flat.size else (0, 0)
    top = max(abs(lo), abs(hi)) << cfg.sample_frac_bits
    narrow = (2 * top + 1) << cfg.weight_bits < 1 << 31
    out = flat.astype(np.int32 if narrow else np.int64)
    # fits: top is below 2**31 (int32) or 2**62 (int64)
    return promote_raw(out, cfg.sample_frac_bits)


def promote_raw(v, sample_frac_bits: int):
    """The interpolator's input promotion ``v << sample_frac_bits`` of integer arrays (type
    kept) or scalars (compiled kernels promote each voxel as they read it)."""
    return v << sample_frac_bits


def interpolate(
    flat: np.ndarray,
    t: InterpTaps,
    cfg: InterpConfig,
    in_frac_bits: int = 0,
    *,
    promoted: bool = False,
) -> np.ndarray:
    """Interpolate a raveled raw array (any sign) at the taps: ``(n,)`` int64 with
    ``in_frac_bits + sample_frac_bits`` fraction bits.  ``promoted``: ``flat`` is
    already :func:`promote`-d."""
    free, corners = lerp_plan(t.frac, cfg)
    v = np.take(flat, t.rows(corners))
    if not promoted:
        v = v.astype(np.int64, copy=False) << cfg.sample_frac_bits
    return lerp_corners(v, t.frac, cfg, free).astype(np.int64, copy=False)


def lerp_plan(frac: np.ndarray, cfg: InterpConfig) -> tuple[list[int], list[int]]:
    """The axes whose lerps matter and the corners they read, for fractions ``(3, ...)``.

    A lerp with weight 0 returns its first operand and one with weight 1.0 (``2**W``)
    its second, exactly, in every rounding mode (the rounded term is 0, or ``b - a`` with
    nothing dropped).  So an axis whose weight is 0 for every sample (samples on a voxel
    slice, as in shear-warp and shear-image orders) or 1.0 for every sample is not
    lerped: its near or far corners are the result, and only those are read.  Returns the
    free axes in ``(z, y, x)`` order and the ``2**k`` corners, ordered by the free axes'
    bits (z most significant), that :func:`lerp_corners` expects.
    """
    one = 1 << cfg.weight_bits
    free, fixed = [], 0
    for axis in range(3):
        f = frac[axis]
        lo, hi = (int(f.min()), int(f.max())) if f.size else (-1, -1)
        if lo == hi and lo in (0, one):
            fixed |= (4 >> axis) if lo == one else 0
        else:
            free.append(axis)
    k = len(free)
    corners = []
    for m in range(1 << k):
        c = fixed
        for i, axis in enumerate(free):
            if (m >> (k - 1 - i)) & 1:
                c |= 4 >> axis
        corners.append(c)
    return free, corners


def lerp_corners(
    v: np.ndarray, frac: np.ndarray, cfg: InterpConfig, free: list[int] | None = None
) -> np.ndarray:
    """The lerps of promoted corners ``v (2**k, ...)`` over the ``free`` axes (default all
    three: ``v`` is ``(8, ...)``, ``c = 4 dz + 2 dy + dx``) with raw fractions ``frac``
    along ``(z, y, x)`` (a ``(3, ...)`` array, or three arrays of which only the free
    axes' are read): x first (four lerps at once), then y (two), then z.  Computed in
    ``v``'s integer type (see :func:`promote`)."""
    for axis in reversed(free if free is not None else [0, 1, 2]):
        f = frac[axis].astype(v.dtype, copy=False)
        v = lerp(v[0::2], v[1::2], f, cfg)  # corners differing in this axis's bit
    return v[0]


def lerp(a: np.ndarray, b: np.ndarray, f: np.ndarray, cfg: InterpConfig) -> np.ndarray:
    """One linear interpolation step: ``a + round((b - a) f / 2**W)`` (``f`` raw UQ1.W),
    in the operands' integer type."""
    return lerp_raw(a, b, f, cfg.weight_bits, ROUNDING_CODES[cfg.rounding])


def lerp_raw(a, b, f, weight_bits: int, code: int):
    """The arithmetic of :func:`lerp` on integer arrays (type kept) or scalars (compiled
    kernels call it too); ``code`` from :data:`hwsim.numerics.ROUNDING_CODES`."""
    return a + round_shift_raw((b - a) * f, weight_bits, code)


def bilinear(v00, v01, v10, v11, fa, fb, cfg: InterpConfig) -> np.ndarray:
    """In-slice interpolation of promoted corners: along ``b`` first, then ``a``.

    ``v<i><j>`` is the corner ``(a0 + i, b0 + j)``.  With ``b`` the faster-varying in-slice
    axis this is exactly :func:`interpolate` of a sample lying on a voxel slice (the
    principal-axis weight 0 or 1 selects one slice exactly), the lerp order x, y, z.
    """
    return bilinear_raw(v00, v01, v10, v11, fa, fb, cfg.weight_bits, ROUNDING_CODES[cfg.rounding])


def bilinear_raw(v00, v01, v10, v11, fa, fb, weight_bits: int, code: int):
    """The arithmetic of :func:`bilinear` on integer arrays or scalars (the functional
    rung's compiled kernel builds each trilinear sample from two of these and a
    :func:`lerp_raw` along z, :func:`lerp_corners`' order)."""
    return lerp_raw(
        lerp_raw(v00, v01, fb, weight_bits, code),
        lerp_raw(v10, v11, fb, weight_bits, code),
        fa,
        weight_bits,
        code,
    )


def error_bound(max_difference: float, cfg: InterpConfig) -> float:
    """Worst-case |fixed - float| in input units for a cell whose voxels differ by at most
    ``max_difference``: half a step per weight and per lerp for the nearest roundings, a
    whole step for the directed ones (floor, truncate)."""
    step = 1.0 if cfg.rounding.startswith("nearest") else 2.0
    return (
        3
        * step
        * (max_difference * 2.0 ** -(cfg.weight_bits + 1) + 2.0 ** -(cfg.sample_frac_bits + 1))
    )
