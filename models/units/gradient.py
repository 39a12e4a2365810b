"""Gradient estimation by central differences; magnitude; unit normals.

# Ref: architectures.md section 9.1 (central differences on samples: Cube-4, VolumePro
#      500; at voxels then interpolated: VolumePro 1000); Levoy 1988.

Differences are kept *unscaled*: ``2 h`` times the derivative, in voxel units (the
golden renderer's ``voxel_gradients`` / ``sample_gradients`` times ``2 * spacing``).

* ``source = "voxel"``: ``v[i+1] - v[i-1]`` at voxels (``2 (v[1] - v[0])`` at edges,
  0 along a 1-voxel axis), format ``gradient.voxel_diff`` (signed, B+2 bits, exact),
  then interpolated with the sample's own taps (S fraction bits).
* ``source = "sample"``: ``s(p + e) - s(p - e)`` of interpolated samples, one voxel
  either side (S fraction bits).

``to_world`` multiplies each component by ``min(spacing) / spacing`` (UQ1.12, VolumePro
1000's gradient correction; an exact no-op on isotropic data) so the vector points along
the world gradient.  ``normals`` returns ``N = -g/|g|`` as SQ1.F, rounded half up by
exact integer division by ``isqrt(|g|^2)``; ``|g| = 0`` gives ``N = 0`` (never NaN).
Small vectors are normalised by a left shift first, so the normal error is below
``2**-F`` per component for every non-zero gradient: half a step of quotient rounding
plus under ``2**-(F+1)`` of magnitude truncation (the normalised integer magnitude is at
least ``2**(F+1)``; the fraction ``isqrt`` drops is under one).  Property-tested in
tests/units/test_gradient.py, which found the ``2**-(F+1) + 2**-(F+2)`` once stated here
exceeded (``g = (0, 222, 32768)``, ``F = 15``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.numerics import round_shift
from models.units.interp import (
    InterpConfig,
    axis_cells,
    corner_offsets,
    lerp_corners,
    lerp_plan,
)

__all__ = [
    "GradientConfig",
    "voxel_differences",
    "voxel_difference",
    "sample_differences",
    "to_world",
    "magnitude",
    "normals",
    "isqrt_raw",
    "normal_raw",
    "normal_float_raw",
    "floor_div_raw",
    "bit_length_raw",
    "LATENCY",
    "II",
]

#: Cycles: the RTL's stage plan (rtl/gradient.py STAGES), pipelined so every stage meets a
#: 125 MHz clock at 0.35 um by the project's depth estimate (issue 34: the square root over
#: 12 stages and the dividers over 6, two restoring steps per stage).  architectures.md
#: 9.3's "gradient 2-3" [I] held only as a 364-gate-deep block (~15 MHz).
LATENCY = 25
II = 1
_RATIO_BITS = 12
_PART = 8192  # samples per part in sample_differences (speed only)


@dataclass(frozen=True, kw_only=True)
class GradientConfig:
    """Gradient source and normal width (defaults: VolumePro 500, [R med] on samples)."""

    source: str = "sample"
    normal_frac_bits: int = 10

    def __post_init__(self) -> None:
        if self.source not in ("sample", "voxel") or not 2 <= self.normal_frac_bits <= 20:
            raise ValueError("gradient: source sample|voxel, normal_frac_bits 2..20")


def voxel_differences(raw: np.ndarray) -> list[np.ndarray]:
    """Central differences at voxels, raveled, as ``[dx, dy, dz]`` (``2 h`` x derivative).

    int32 when every voxel fits in 29 bits (then every difference, at most twice the
    range, fits too: a quarter of the int64 bytes to write), else int64; exact either way.
    """
    return [voxel_difference(raw, axis) for axis in (2, 1, 0)]


def voxel_difference(raw: np.ndarray, axis: int) -> np.ndarray:
    """The central differences of :func:`voxel_differences` along one index ``axis``
    (0 = z, 1 = y, 2 = x), raveled: one array at a time, so a caller that narrows each
    before asking for the next never holds three wide ones.  The voxels are widened as
    they are read (no wide copy of the volume)."""
    raw = np.asarray(raw)
    small = raw.size == 0 or (int(raw.min()) >= -(1 << 29) and int(raw.max()) < 1 << 29)
    wide = np.int32 if small else np.int64
    n = raw.shape[axis]
    if n < 2:
        return np.zeros(raw.size, dtype=wide)
    d = np.empty(raw.shape, dtype=wide)
    v = np.moveaxis(raw, axis, 0)
    dv = np.moveaxis(d, axis, 0)
    np.subtract(v[2:], v[:-2], out=dv[1:-1], dtype=wide)  # into place: no temporary
    dv[0] = 2 * (v[1].astype(wide) - v[0])
    dv[-1] = 2 * (v[-1].astype(wide) - v[-2])
    return d.ravel()


def sample_differences(
    flat: np.ndarray,
    zyx: np.ndarray,
    shape: tuple[int, int, int],
    cfg: InterpConfig,
    *,
    promoted: bool = False,
    center: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """``s(p + e) - s(p - e)`` per axis, ``(n, 3)`` in ``(x, y, z)``, S fraction bits.

    Each neighbour ``p +- e`` (``e`` one voxel along one axis, added in float64) is
    interpolated exactly as :func:`~models.units.interp.interpolate` would at that
    position: only the moved axis's cell and weight differ from the sample's own, so one
    cell computation covers the six moved coordinates, and the six neighbours share one
    gather and one set of lerps.  ``promoted``: ``flat`` is already
    :func:`~models.units.interp.promote`-d; ``center``: the samples' own cells and
    weights ``(i0 (3, n), frac (3, n))`` when the caller has them (``InterpTaps.cells``
    and ``frac``).
    """
    n = zyx.shape[0]
    if n == 0:
        return np.empty((0, 3), dtype=np.int64)
    if n > _PART:  # 48 corner reads per sample: parts keep the temporaries in cache
        return np.concatenate(
            [
                sample_differences(
                    flat,
                    zyx[s : s + _PART],
                    shape,
                    cfg,
                    promoted=promoted,
                    center=None if center is None else tuple(c[:, s : s + _PART] for c in center),
                )
                for s in range(0, n, _PART)
            ]
        )
    axis_of = np.array([0, 0, 1, 1, 2, 2])  # neighbour k moves axis k // 2, ahead if even
    hi = np.asarray(shape, dtype=np.float64) - 1.0
    p = np.ascontiguousarray(zyx.T)  # (3, n), rows contiguous
    moved = p[axis_of] + np.array([1.0, -1.0] * 3)[:, None]
    if center is None:
        i0, frac = axis_cells(
            np.concatenate([p, moved]), np.concatenate([hi, hi[axis_of]])[:, None], cfg
        )
        i0, frac, ia, fa = i0[:3], frac[:3], i0[3:], frac[3:]
    else:
        i0, frac = center
        ia, fa = axis_cells(moved, hi[axis_of][:, None], cfg)
    strides = np.array([shape[1] * shape[2], shape[2], 1])
    base = i0[0] * strides[0] + i0[1] * strides[1] + i0[2]
    cells = base + (ia - i0[axis_of]) * strides[axis_of][:, None]  # (6, n)
    # Neighbour k's weight along axis a is the sample's own, except fa[k] when k moves a.
    # Which axes need lerps is decided from each axis's extremes over all six neighbours.
    ends = np.array(
        [
            [
                min(frac[a].min(), fa[2 * a : 2 * a + 2].min()),
                max(frac[a].max(), fa[2 * a : 2 * a + 2].max()),
            ]
            for a in range(3)
        ]
    )
    free, corners = lerp_plan(ends, cfg)
    v = np.take(flat, cells + corner_offsets(shape)[corners, None, None])  # (2**k, 6, n)
    if not promoted:
        v = v.astype(np.int64, copy=False) << cfg.sample_frac_bits
    weights: list[np.ndarray | None] = [None, None, None]
    for a in free:
        w = np.empty((6, n), dtype=v.dtype)
        w[:] = frac[a]
        w[2 * a : 2 * a + 2] = fa[2 * a : 2 * a + 2]
        weights[a] = w
    s = lerp_corners(v, weights, cfg, free).astype(np.int64)  # (6, n)
    return (s[0::2] - s[1::2])[::-1].T.copy()


def to_world(
    g: np.ndarray, spacing_zyx: tuple[float, float, float], frac_bits: int, cfg: GradientConfig
) -> np.ndarray:
    """Scale ``(n, 3)`` xyz differences by ``min(spacing) / spacing`` per axis (UQ1.12)."""
    spacing_xyz = np.asarray(spacing_zyx, dtype=np.float64)[::-1]
    ratio = np.floor(spacing_xyz.min() / spacing_xyz * (1 << _RATIO_BITS) + 0.5).astype(np.int64)
    if np.all(ratio == 1 << _RATIO_BITS):
        return g
    return round_shift(g * ratio, _RATIO_BITS, "nearest-up")


def magnitude(g: np.ndarray) -> np.ndarray:
    """``floor(sqrt(gx^2 + gy^2 + gz^2))`` exactly (integer square root, vectorised)."""
    return isqrt_raw(np.einsum("ij,ij->i", g, g))


def normals(g: np.ndarray, cfg: GradientConfig) -> np.ndarray:
    """Unit normals ``-g/|g|`` as SQ1.F raw integers; zero where ``g`` is zero.

    Small vectors are first shifted left (a leading-zero normaliser) until their integer
    magnitude has at least ``F + 2`` bits (is at least ``2**(F+1)``), so the magnitude's
    truncation costs under ``2**-(F+1)`` per component.

    Domain: components below ``2**30`` in magnitude (``|g|**2 < 2**62``), which every
    datapath allows: a difference of two samples of at most 16 voxel bits and 12 fraction
    bits, or a voxel difference, has at most 30 bits with its sign.
    """
    g = np.asarray(g, dtype=np.int64)
    return np.stack(normal_raw(g[:, 0], g[:, 1], g[:, 2], cfg.normal_frac_bits), axis=1)


# The two functions below are the unit's arithmetic, written once for int64 arrays (the
# vectorised API above) and int64 scalars (the functional rung's compiled kernel).


def isqrt_raw(s):
    """``floor(sqrt(s))`` of int64 ``0 <= s < 2**62`` (array or scalar), exactly: the float
    root, then one correction step each way (whose squares must fit int64)."""
    r = np.int64(np.floor(np.sqrt(np.float64(s))))
    r = r + ((r + 1) * (r + 1) <= s)
    return r - (r * r > s)


def normal_raw(gx, gy, gz, f: int):
    """``(nx, ny, nz)``: :func:`normals` of the vector(s) ``(gx, gy, gz)`` (int64 arrays
    or scalars), SQ1.``f``.  A zero vector gives 0: its numerators are 0 and the divisor
    is 1, so the rounded quotient ``(0 + 1) // 2`` is 0."""
    m0 = isqrt_raw(gx * gx + gy * gy + gz * gz)
    bits = bit_length_raw(np.maximum(m0, 1))
    shift = np.minimum(np.maximum(f + 2 - bits, 0), 40)
    gx, gy, gz = gx << shift, gy << shift, gz << shift
    safe = np.maximum(isqrt_raw(gx * gx + gy * gy + gz * gz), 1)
    limit = 1 << f
    return (
        np.minimum(np.maximum(floor_div_raw(2 * (-gx << f) + safe, 2 * safe), -limit), limit),
        np.minimum(np.maximum(floor_div_raw(2 * (-gy << f) + safe, 2 * safe), -limit), limit),
        np.minimum(np.maximum(floor_div_raw(2 * (-gz << f) + safe, 2 * safe), -limit), limit),
    )


def bit_length_raw(m):
    """Bits of non-negative int64 ``m`` (arrays or scalars): ``floor(log2 m) + 1`` for
    ``m >= 1``, 0 for 0, by a six-step binary search on shifts (exact for every int64;
    the float ``log2`` it replaces agreed below ``2**45``, and ``|g|`` stays below
    ``2**32``: ``|g|**2`` must fit int64)."""
    b = 32 * ((m >> 32) > 0)  # written out: a loop over a tuple is a loop when compiled
    b = b + 16 * ((m >> (b + 16)) > 0)
    b = b + 8 * ((m >> (b + 8)) > 0)
    b = b + 4 * ((m >> (b + 4)) > 0)
    b = b + 2 * ((m >> (b + 2)) > 0)
    b = b + ((m >> (b + 1)) > 0)
    return b + (m > 0)


def floor_div_raw(n, d):
    """``n // d`` of int64 ``n`` and ``d > 0`` (arrays or scalars), exactly, for quotients
    below ``2**50`` in magnitude (here at most ``2**f + 1``): the float64 quotient is then
    within one of the exact one (three roundings of relative ``2**-53``), and one
    remainder test each way corrects it.  A float division and two compares cost far
    less than an integer division."""
    q = np.int64(np.floor(np.float64(n) / np.float64(d)))
    r = n - q * d
    return q - (r < 0) + (r >= d)


#: Below this ``|g|**2`` (and ``F <= 24``) every intermediate of :func:`normal_raw` is an
#: integer under ``2**53``, so float64 holds it exactly.
_FLOAT_EXACT = 2.0**52


def normal_float_raw(gx, gy, gz, f: int):
    """:func:`normal_raw` of one vector (int64 scalars), computed in float64: the same
    integers.  With ``|g|**2 < 2**52`` and ``f <= 24`` every value is an integer below
    ``2**53`` (exact in float64): the squares and their sums; the roots, since a float
    root of an exact ``s < 2**52`` floors to ``isqrt(s)`` (it rounds up to an integer ``k``
    only when ``k > 2**26``); the shift, a power-of-two scale (the shifted root is the
    unshifted float root scaled, so one square root serves both); and the quotients,
    whose float division floors exactly (a non-integer quotient lies at least ``1 / d``,
    ``d <= 2**27``, from an integer, more than half its ulp).  Outside that range it is
    :func:`normal_raw`.  Half the time of :func:`normal_raw` in compiled loops (fewer
    int64/float64 conversions; tests/units/test_gradient.py compares the two)."""
    x, y, z = np.float64(gx), np.float64(gy), np.float64(gz)
    s0 = x * x + y * y + z * z
    if s0 >= _FLOAT_EXACT or f > 24:
        return normal_raw(gx, gy, gz, f)
    root = np.sqrt(s0)
    bits = bit_length_raw(max(np.int64(np.floor(root)), 1))
    scale = np.float64(np.int64(1) << min(max(f + 2 - bits, 0), 40))
    safe = max(np.floor(root * scale), 1.0)  # isqrt of the shifted components' squares
    top, d = -2.0 * scale * np.float64(np.int64(1) << f), 2.0 * safe
    limit = np.float64(np.int64(1) << f)
    return (
        np.int64(min(max(np.floor((top * x + safe) / d), -limit), limit)),
        np.int64(min(max(np.floor((top * y + safe) / d), -limit), limit)),
        np.int64(min(max(np.floor((top * z + safe) / d), -limit), limit)),
    )
