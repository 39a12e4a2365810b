"""Image and value error metrics: RMSE, PSNR, max abs error, ULP distance.

All take float arrays of the same shape; a trailing channel axis is kept by the
``per_channel`` helper.  PSNR uses an explicit ``peak`` (1.0 for images in ``[0, 1]``) and
is ``inf`` for identical inputs.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "rmse",
    "psnr",
    "max_abs_error",
    "ulp_distance",
    "per_channel",
    "agreement",
    "ROUND_OFF",
    "EXACT_MATCHES",
]

#: Largest error, as a share of the peak, that float64 round-off explains when two
#: float64 renderers reach the same result by different operation orders: a 53-bit
#: mantissa loses at most 1.1e-16 per operation, and a ray takes at most ~10^4 dependent
#: steps.  The narrowest fixed-point rung (8-16 bit fractions) errs by 1e-5 or more, so
#: the two never meet.
ROUND_OFF = 1e-12
#: :func:`agreement` results that a table shows as exact.
EXACT_MATCHES = ("identical", "round-off")


def _pair(ref: np.ndarray, test: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ref = np.asarray(ref, dtype=np.float64)
    test = np.asarray(test, dtype=np.float64)
    if ref.shape != test.shape:
        raise ValueError(f"shapes differ: {ref.shape} vs {test.shape}")
    return ref, test


def rmse(ref: np.ndarray, test: np.ndarray) -> float:
    """Root-mean-square error."""
    ref, test = _pair(ref, test)
    return float(np.sqrt(np.mean((ref - test) ** 2)))


def psnr(ref: np.ndarray, test: np.ndarray, peak: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB, ``10 log10(peak^2 / MSE)``; ``inf`` if equal."""
    ref, test = _pair(ref, test)
    mse = float(np.mean((ref - test) ** 2))
    return float("inf") if mse == 0 else float(10 * np.log10(peak**2 / mse))


def max_abs_error(ref: np.ndarray, test: np.ndarray) -> float:
    """Largest absolute difference."""
    ref, test = _pair(ref, test)
    return float(np.max(np.abs(ref - test))) if ref.size else 0.0


def agreement(ref: np.ndarray, test: np.ndarray, peak: float = 1.0) -> str:
    """``"identical"``, ``"round-off"`` (max abs error <= :data:`ROUND_OFF` x ``peak``) or
    ``"differs"``."""
    error = max_abs_error(ref, test)
    if error == 0.0:
        return "identical"
    return "round-off" if error <= ROUND_OFF * abs(peak) else "differs"


def ulp_distance(a_raw: np.ndarray, b_raw: np.ndarray) -> int:
    """Largest distance in units of the last place between two raw integer arrays."""
    a = np.asarray(a_raw, dtype=np.int64)
    b = np.asarray(b_raw, dtype=np.int64)
    return int(np.max(np.abs(a - b))) if a.size else 0


def per_channel(ref: np.ndarray, test: np.ndarray, peak: float = 1.0) -> dict[str, dict]:
    """RMSE, PSNR and max abs error per channel of ``(..., C)`` images (or one scalar)."""
    ref, test = _pair(ref, test)
    if ref.ndim < 3:
        return {
            "value": {
                "rmse": rmse(ref, test),
                "psnr": psnr(ref, test, peak),
                "max_abs": max_abs_error(ref, test),
            }
        }
    names = "RGBA" if ref.shape[-1] == 4 else [str(i) for i in range(ref.shape[-1])]
    return {
        names[c]: {
            "rmse": rmse(ref[..., c], test[..., c]),
            "psnr": psnr(ref[..., c], test[..., c], peak),
            "max_abs": max_abs_error(ref[..., c], test[..., c]),
        }
        for c in range(ref.shape[-1])
    }
