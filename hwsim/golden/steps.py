"""The step engine shared by every sample plan, and the shear-warp's 2-D warp filter.

# Ref: Lacroute & Levoy, SIGGRAPH 1994 (the base-plane warp); Levoy, IEEE CG&A 1988
#      (front-to-back order).

A plan ray ``r`` takes one sample at every global step ``j`` in ``[j_lo[r], j_hi[r]]``.
:func:`run_steps` walks ``j`` front to back and keeps an *active set*: rays join at their
``j_lo``, leave after their ``j_hi`` or when the caller marks them dead (early ray
termination), so each step costs O(active rays), not O(image).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

if TYPE_CHECKING:
    from hwsim.golden.positions import SamplePlan

__all__ = ["Step", "all_alive", "run_steps", "linear_range", "bilinear_2d"]

_TINY = 1e-12


@dataclass(frozen=True)
class Step:
    """One front-to-back step: a sample for each listed ray.

    ``rays`` are int64 flat indices into the accumulation image (row-major plan
    ``shape``; each ray at most once); ``zyx`` are float64 index coordinates ``(n, 3)``;
    ``dt`` is the world distance each sample stands for (a float, or ``(n,)``); ``view``
    is the unit world ``(x, y, z)`` vector toward the viewer, ``(3,)`` when shared by all
    rays or ``(n, 3)`` (perspective), None when unknown (a step built by hand).
    """

    rays: np.ndarray
    zyx: np.ndarray
    dt: float | np.ndarray
    view: np.ndarray | None = None


def run_steps(plan: SamplePlan, alive: np.ndarray | None) -> Iterator[Step]:
    """Yield ``plan.n_steps`` steps; rays whose ``alive`` entry is False are dropped."""
    # The plan's rays in the order they join (``plan.reordered``): the active set is then
    # a rising run of positions into its arrays, read front to back at every step (not
    # scattered over them), and each step holds the same rays, positions and order.
    walk = plan.reordered(np.argsort(plan.j_lo, kind="stable"))
    joins = np.searchsorted(walk.j_lo, np.arange(plan.n_steps + 1), side="left")
    per_ray_dt = isinstance(walk._dt, np.ndarray)
    per_ray_view = walk._view.ndim == 2
    active = np.empty(0, dtype=np.int64)
    check = alive is not None
    flags = alive if check else _NO_ALIVE
    for j in range(plan.n_steps):
        if joins[j + 1] > joins[j]:
            active = np.concatenate([active, np.arange(joins[j], joins[j + 1])])
        active, rays = _advance(active, j, walk.j_hi, walk.ray_ids, flags, check)
        yield Step(
            rays,
            walk.position(j, active),
            walk._dt[active] if per_ray_dt else walk._dt,
            walk._view[active] if per_ray_view else walk._view,
        )


_NO_ALIVE = np.ones(0, dtype=bool)


@numba.njit(cache=True, nogil=True)
def all_alive(alive, rays):  # pragma: no cover - compiled
    """``alive[rays].all()`` without the gathered copy, stopping at the first dead ray
    (a back end checks every step's rays; mostly all alive)."""
    for i in range(rays.size):
        if not alive[rays[i]]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _advance(active, j, j_hi, ray_ids, alive, check):  # pragma: no cover - compiled
    """The active plan rays that take a sample at step ``j`` (``j_hi >= j`` and, when
    ``check``, ``alive`` at their accumulation ray), in order, and those accumulation
    rays: the active set's update in one pass instead of four array expressions."""
    keep = np.empty(active.size, dtype=np.int64)
    rays = np.empty(active.size, dtype=ray_ids.dtype)
    n = 0
    for i in range(active.size):
        r = active[i]
        if j_hi[r] >= j and (not check or alive[ray_ids[r]]):
            keep[n] = r
            rays[n] = ray_ids[r]
            n += 1
    return keep[:n], rays[:n]


def linear_range(
    start: np.ndarray, delta: np.ndarray, lo: float | np.ndarray, hi: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Real ``j`` range, per ray, where ``start + j * delta`` is inside ``[lo, hi]``.

    ``start`` is ``(m, 3)``, ``delta`` ``(3,)`` or ``(m, 3)``; bounds are inclusive with a
    1e-9 tolerance.  Returns float ``(m,)`` arrays ``ceil`` / ``floor``-ed to integers
    (``-inf`` / ``inf`` where unconstrained; ``j_lo > j_hi`` where the box is missed;
    NaN where a position or step is NaN).  One compiled pass (:func:`_linear_range_rows`).
    """
    start = np.ascontiguousarray(start, dtype=np.float64).reshape(-1, 3)
    delta = np.asarray(delta, dtype=np.float64)
    if delta.ndim == 1:
        delta = delta.reshape(1, 3)  # one step shared by every ray
    elif delta.shape[0] > 1 and delta.strides[0] == 0:
        delta = delta[:1]  # a broadcast row
    delta = np.ascontiguousarray(np.broadcast_to(delta, (delta.shape[0], 3)))
    lo_b = np.broadcast_to(np.asarray(lo, dtype=np.float64), (3,)) - 1e-9
    hi_b = np.broadcast_to(np.asarray(hi, dtype=np.float64), (3,)) + 1e-9
    first, last = np.empty(start.shape[0]), np.empty(start.shape[0])
    _linear_range_rows(start, delta, lo_b, hi_b, first, last)
    return first, last


@numba.njit(cache=True, nogil=True)
def _nan_or(a, b, take_b):  # pragma: no cover - compiled
    """NumPy's NaN-propagating ``maximum`` / ``minimum``: NaN if either is NaN, else
    ``b`` where ``take_b``."""
    if a != a:
        return a
    if b != b or take_b:
        return b
    return a


@numba.njit(cache=True, nogil=True)
def _linear_range_rows(start, delta, lo_b, hi_b, first, last):  # pragma: no cover
    """:func:`linear_range`'s array expression one ray at a time, the same float64
    operations (``(lo - start) / delta``, ``(hi - start) / delta``, a face parallel to
    the step unconstrained inside and missed outside, max / min over the axes with NaN
    propagated, ``ceil`` / ``floor``), so the same values (up to the sign of a zero,
    which the callers' integer conversions do not see)."""
    shared = delta.shape[0] == 1
    for i in range(start.shape[0]):
        row = 0 if shared else i
        f, g = 0.0, 0.0
        for c in range(3):
            s, d = start[i, c], delta[row, c]
            if abs(d) < _TINY:
                inside = s >= lo_b[c] and s <= hi_b[c]
                fc, gc = (-np.inf, np.inf) if inside else (np.inf, -np.inf)
            else:
                e1, e2 = (lo_b[c] - s) / d, (hi_b[c] - s) / d
                fc, gc = _nan_or(e1, e2, e2 < e1), _nan_or(e1, e2, e2 > e1)
            if c == 0:
                f, g = fc, gc
            else:
                f, g = _nan_or(f, fc, fc > f), _nan_or(g, gc, gc < g)
        first[i], last[i] = np.ceil(f), np.floor(g)


def bilinear_2d(image: np.ndarray, a: np.ndarray, b: np.ndarray, background: float) -> np.ndarray:
    """Sample ``image[a, b, ...]`` bilinearly; points off the image blend to ``background``.

    ``a`` indexes rows and ``b`` columns, pixel centres at integers; float64 out.
    """
    rows, cols = image.shape[:2]
    pad = np.full((rows + 2, cols + 2) + image.shape[2:], background, dtype=np.float64)
    pad[1:-1, 1:-1] = image
    channels = pad.reshape(rows + 2, cols + 2, -1)
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    out = np.empty((a.size, channels.shape[2]))
    _bilinear_rows(channels, a.ravel(), b.ravel(), out)
    return out.reshape(a.shape + image.shape[2:])


@numba.njit(cache=True, nogil=True)
def _clip(v, hi):  # pragma: no cover - compiled
    """``np.clip(v, 0.0, hi)`` of one float (NaN stays NaN)."""
    if v < 0.0:
        return 0.0
    if v > hi:
        return hi
    return v


@numba.njit(cache=True, nogil=True)
def _bilinear_rows(pad, a, b, out):  # pragma: no cover - compiled
    """``bilinear_2d``'s filter, one point at a time: the same float64 operations in the
    same order as the array expression it replaced (``a + 1`` and ``b + 1`` clipped to
    the padded image, then ``(1 - fa) ((1 - fb) p00 + fb p01) + fa ((1 - fb) p10 + fb
    p11)``, no fused multiply-adds), so the same bits."""
    rows, cols = pad.shape[0] - 2, pad.shape[1] - 2
    for i in range(a.shape[0]):
        ai = _clip(a[i] + 1.0, rows + 1.0)
        bi = _clip(b[i] + 1.0, cols + 1.0)
        a0 = min(np.int64(np.floor(ai)), rows)
        b0 = min(np.int64(np.floor(bi)), cols)
        fa, fb = ai - a0, bi - b0
        for c in range(pad.shape[2]):
            near = (1 - fb) * pad[a0, b0, c] + fb * pad[a0, b0 + 1, c]
            far = (1 - fb) * pad[a0 + 1, b0, c] + fb * pad[a0 + 1, b0 + 1, c]
            out[i, c] = (1 - fa) * near + fa * far
