"""``x ** e`` in float64 through the C library's ``pow``, the same bits in NumPy code and
in compiled code.

NumPy's ``**`` on float64 arrays uses its own vectorised power (and square or square root
for the exponents 2 and 0.5), which differs from the C library's ``pow`` in the last bit
for most arguments.  The golden renderer's step engine and its compiled ray walk
(:mod:`hwsim.golden.raywalk`) must produce the same image, so both raise with this one
compiled function (the Phong specular term and the opacity correction).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["power", "power_scalar"]


@numba.njit(cache=True, nogil=True)
def power_scalar(x, e):  # pragma: no cover - compiled
    """``x ** e`` for float64 ``x`` and ``e`` (C ``pow``)."""
    return x**e


@numba.njit(cache=True, nogil=True)
def _power_rows(x, e, out):  # pragma: no cover - compiled
    for i in range(x.shape[0]):
        out[i] = power_scalar(x[i], e[i])


@numba.njit(cache=True, nogil=True)
def _power_by(x, e, out):  # pragma: no cover - compiled
    for i in range(x.shape[0]):
        out[i] = power_scalar(x[i], e)


def power(x: np.ndarray, e: float | np.ndarray) -> np.ndarray:
    """``x ** e`` elementwise (``x`` any shape; ``e`` a scalar or an array of ``x``'s
    shape), float64."""
    x = np.asarray(x, dtype=np.float64)
    flat = np.ascontiguousarray(x).ravel()
    out = np.empty_like(flat)
    if np.ndim(e) == 0:
        _power_by(flat, float(e), out)
    else:
        exps = np.ascontiguousarray(np.broadcast_to(np.asarray(e, dtype=np.float64), x.shape))
        _power_rows(flat, exps.ravel(), out)
    return out.reshape(x.shape)
