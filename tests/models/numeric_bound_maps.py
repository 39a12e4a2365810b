"""The formats' maps and the vector helpers of the derived bound (numeric_bound.py):
the documented roundings (to LSBs, to fraction bits, unorm storage read back as UQ1.12),
the range of a piecewise-linear transfer function over an interval, the voxel conversion
of docs/numerics.md, the chord between unit vectors, central differences at voxels."""

from __future__ import annotations

import numpy as np

ONE12 = 4096.0
SQRT3 = float(np.sqrt(3.0))


def _round(x, rounding: str):
    """A real (scaled to LSBs) rounded to an integer by a documented rounding mode."""
    if rounding == "nearest-up":
        return np.floor(x + 0.5)
    if rounding == "nearest-even":
        return np.round(x)
    if rounding == "truncate":
        return np.trunc(x)
    return np.floor(x)


def _half_lsb(rounding: str) -> float:
    """Largest rounding error, in LSBs, of a rounding mode (nearest: 1/2, directed: 1)."""
    return 0.5 if rounding.startswith("nearest") else 1.0


def _q(x, bits: int):
    """Nearest-up quantisation to ``bits`` fraction bits (SQ1.F vectors, UQ4.8
    coefficients, UQ4.F exponents): ``floor(x 2**bits + 1/2) / 2**bits``."""
    return np.floor(np.asarray(x, dtype=np.float64) * 2.0**bits + 0.5) / 2.0**bits


def _unorm_to_uq12(x, bits: int):
    """A [0, 1] value stored as unorm ``bits`` (nearest-up) and read out as UQ1.12
    (``round(u 4096 / (2**n - 1))`` half up): both steps monotone, 0 and 1 exact."""
    full = (1 << bits) - 1
    stored = np.floor(np.asarray(x, dtype=np.float64) * full + 0.5)
    return np.floor((stored * (2 * ONE12) + full) / (2 * full)) / ONE12


def _tf_range(points: np.ndarray, column: np.ndarray, x0, x1):
    """Min and max of a piecewise-linear function (``numpy.interp``: constant outside its
    points) over ``[x0, x1]``: the ends and the control points inside."""
    a, b = np.interp(x0, points, column), np.interp(x1, points, column)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    for xk, yk in zip(points, column, strict=True):
        inside = (x0 < xk) & (xk < x1)
        lo = np.where(inside, np.minimum(lo, yk), lo)
        hi = np.where(inside, np.maximum(hi, yk), hi)
    return lo, hi


def _voxel_map(volume, bits: int) -> tuple[float, float, float]:
    """``(offset, scale, conversion error in raw units)`` of docs/numerics.md's voxel
    rules: unsigned data of at most ``bits`` bits shifted up (exact), signed data whose
    range fits offset by its minimum (exact), anything else mapped linearly onto
    ``[0, 2**bits - 1]`` rounding half up (half a raw step)."""
    data = volume.data
    top = (1 << bits) - 1
    lo, hi = volume.value_range
    if data.dtype.kind == "u" and volume.bits <= bits and hi <= (1 << volume.bits) - 1:
        return 0.0, 2.0 ** -(bits - volume.bits), 0.0
    if data.dtype.kind in "iu" and hi - lo <= top:
        return float(lo), 1.0, 0.0
    if hi <= lo:
        return float(lo), 1.0, 0.0
    return float(lo), (hi - lo) / top, 0.5


def _chord(r):
    """Largest distance between the unit vectors of ``g`` and ``g + e`` with
    ``|e| <= r |g|``: ``2 sin(theta / 2)`` with ``sin theta = r``; 2 when ``r >= 1``."""
    r = np.asarray(r, dtype=np.float64)
    inside = np.sqrt(np.maximum(1.0 - np.minimum(r, 1.0) ** 2, 0.0))
    return np.where(r < 1.0, np.sqrt(np.maximum(2.0 - 2.0 * inside, 0.0)), 2.0)


def _voxel_differences(raw: np.ndarray) -> list[np.ndarray]:
    """``[dx, dy, dz]`` central differences at voxels (``2 h`` times the derivative, raw
    units): ``v[i+1] - v[i-1]``, ``2 (v[1] - v[0])`` at the faces, 0 on a 1-voxel axis."""
    out = []
    for axis in (2, 1, 0):
        n = raw.shape[axis]
        d = np.zeros_like(raw)
        if n >= 2:
            v = np.moveaxis(raw, axis, 0)
            dv = np.moveaxis(d, axis, 0)
            dv[1:-1] = v[2:] - v[:-2]
            dv[0] = 2 * (v[1] - v[0])
            dv[-1] = 2 * (v[-1] - v[-2])
        out.append(d)
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    if v.ndim == 1:
        n = float(np.linalg.norm(v))
        return v / n if n > 1e-12 else np.zeros(3)
    return _unit_rows(v)


def _unit_rows(v: np.ndarray) -> np.ndarray:
    n = _norm(v)[:, None]
    return np.divide(v, n, out=np.zeros_like(v), where=n > 1e-12)


def _norm(v: np.ndarray):
    v = np.asarray(v, dtype=np.float64)
    return np.sqrt(np.sum(v * v, axis=-1))


def _rowdot(n: np.ndarray, v: np.ndarray) -> np.ndarray:
    v = np.broadcast_to(v, n.shape)
    return np.sum(n * v, axis=1)


def _power(x, n: float):
    """``x**n`` for ``x`` in [0, 1] with ``0**n = 0`` for ``n > 0``."""
    return np.power(np.asarray(x, dtype=np.float64), n)
