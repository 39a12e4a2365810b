"""Empty-space leaping of ideal-ray plans, compiled: :meth:`SamplePlan.leap`'s march
one ray at a time, the same float64 operations, the same step ranges.

# Ref: Levoy, "Efficient Ray Tracing of Volume Data", ACM TOG 1990 (empty-space
#      skipping by distance); hwsim.golden.occupancy (the distance field).

:meth:`~hwsim.golden.positions.SamplePlan.leap` marches every ray from each end past
blocks the occupancy marks empty, in NumPy over the set of rays still marching.  For
``ray`` plans (the golden renderer's default, every frame of a rotation) that march is
serial NumPy and a third of a compiled golden frame; here each ray marches in compiled
code with the NumPy march's arithmetic: the position ``o + t d`` with ``t = (k_first +
k_dir j) dt``, ``numpy.floor_divide``'s rule for the block, the same skip and face
formulas, the same bounds.  Two shortcuts keep every result: a power-of-two block's
quotient is a product by its exact inverse, and the face term is computed first for the
longest step's axis only (the minimum over the axes is at most that term, so when the
distance's leap already reaches past it the other two are not needed).  A ray's march is
one serial chain of dependent float operations, so four rays march at once, a step each
in turn (a lane whose ray is done takes the next): the processor overlaps their chains,
about 1.4x faster, and every ray's own operations are the same.

An *empty* ray (the forward march ran past ``j_hi``) comes back in one canonical form,
``j_lo = j_hi + 1`` with ``j_hi`` unchanged, and takes no backward march: the NumPy
march does the same, and :meth:`~hwsim.golden.positions.SamplePlan.leap` drops such rays
at once (``j_lo > j_hi``), so no consumer ever reads their ends.  Other steps cost less
with the same results: a block index is the float quotient's truncation (the same as its
floor on a clipped, non-negative position), and a block at distance 1 leaps to the
first sample out of the block without the distance's division (``(c - 1) block - 1e-6``
is negative there, so that leap is below one step and the maximum ignores it); when the
rays share one step vector (parallel views) the distance's leap of every distance is
computed once, by the same operations, into a table; the distance field is read as int8
or int16 when its values fit (a smaller footprint for the random reads).
``tests/golden/test_leap_rays.py`` checks the step ranges are the NumPy march's exactly.
"""

from __future__ import annotations

import math
import weakref

import numba
import numpy as np

__all__ = ["leap_ray_plan"]

_TINY = 1e-12


def leap_ray_plan(plan, occupancy) -> tuple[np.ndarray, np.ndarray]:
    """New ``(j_lo, j_hi)`` of a ``ray`` ``plan`` leapt past ``occupancy``'s empty blocks
    (rays left without samples have ``j_lo > j_hi``, canonically ``j_lo = j_hi + 1``)."""
    delta = np.ascontiguousarray(np.reshape(plan._delta, (-1, 3)))
    # ``|delta|_inf`` of each step vector (one row when the rays share it): the maximum
    # of the three magnitudes, exactly the NumPy march's.
    reach = np.abs(delta).max(axis=1)
    j_lo, j_hi = plan.j_lo.copy(), plan.j_hi.copy()
    _march(
        np.ascontiguousarray(plan._o),
        np.ascontiguousarray(plan._d.reshape(-1, 3)),
        int(plan.k_first),
        int(plan.k_dir),
        float(plan._dt),
        delta,
        reach,
        plan.n - 1.0,
        int(occupancy.block),
        *_compact(occupancy.distance),
        j_lo,
        j_hi,
    )
    return j_lo, j_hi


#: The last few distance fields in their narrowest integer type, by the field's identity
#: (a weak reference checks it is still the same array): an occupancy is the volume's
#: and the transfer function's, so the frames of a turntable share one.
_COMPACT: dict[int, tuple[weakref.ref, np.ndarray, int]] = {}


def _compact(distance: np.ndarray) -> tuple[np.ndarray, int]:
    """``distance`` as int8 or int16 when its values fit (the same values, a quarter or
    an eighth of the memory the march reads at random), else as it is; and its largest
    value."""
    found = _COMPACT.get(id(distance))
    if found is not None and found[0]() is distance:
        return found[1:]
    top = int(distance.max(initial=0))
    low = int(distance.min(initial=0))
    narrow = distance
    for kind in (np.int8, np.int16):
        if np.iinfo(kind).min <= low and top <= np.iinfo(kind).max:
            narrow = distance.astype(kind)
            break
    narrow = np.ascontiguousarray(narrow)
    while len(_COMPACT) >= 4:
        _COMPACT.pop(next(iter(_COMPACT)))
    _COMPACT[id(distance)] = (weakref.ref(distance), narrow, top)
    return narrow, top


@numba.njit(cache=True, nogil=True)
def _floor_divide(a, b):  # pragma: no cover - compiled
    """``numpy.floor_divide(a, b)`` for float64 (NumPy's ``npy_divmod``)."""
    mod = np.fmod(a, b)
    div = (a - mod) / b
    if mod != 0.0:
        if (b < 0) != (mod < 0):
            div -= 1.0
    if div != 0.0:
        floordiv = math.floor(div)
        if div - floordiv > 0.5:
            floordiv += 1.0
        return floordiv
    return math.copysign(0.0, a / b)


@numba.njit(inline="always")
def _face(step, p, blk, block):  # pragma: no cover - compiled
    """Steps of ``step`` from ``p`` to the face of block ``blk`` it moves towards."""
    if step > 0:
        return ((blk + 1) * block - p) / abs(step)
    return (p - blk * block) / abs(step)


_LANES = 4


@numba.njit(inline="always")
def _axis_max(s0, s1, s2):  # pragma: no cover - compiled
    """Index of the longest of three steps (the first on ties)."""
    return 0 if abs(s0) >= abs(s1) and abs(s0) >= abs(s2) else (1 if abs(s1) >= abs(s2) else 2)


@numba.njit(inline="always")
def _block_rule(block):  # pragma: no cover - compiled
    """The block as a float, whether it is a power of two, and its inverse then.  A
    power-of-two block: the quotient of a clipped (>= 0) position is exact, so its floor
    is ``numpy.floor_divide``'s without the remainder (``fmod`` was half the march), and
    dividing by it is multiplying by its inverse, exactly; the floor of a non-negative
    quotient is its truncation to an integer."""
    fblock = np.float64(block)
    exact = block > 0 and (block & (block - 1)) == 0
    return fblock, exact, 1.0 / fblock if exact else 0.0


@numba.njit(cache=True, nogil=True)
def _leap_table(dist_max, block, reach):  # pragma: no cover - compiled
    """One step vector for every ray: the distance's leap of each distance ``0 ..
    dist_max``, once (the same float operations as a step's; a table lookup instead of a
    division a step).  ``dist_max < 0``: no table (rays with their own step vectors)."""
    leap_of = np.empty(max(dist_max + 1, 0))
    for c in range(leap_of.size):
        leap_of[c] = math.floor(((c - 1) * block - 1e-6) / reach)
    return leap_of


@numba.njit(inline="always")
def _take_next(k, nxt, sign, ray, at, j_lo, j_hi):  # pragma: no cover - compiled
    """Lane ``k`` takes ray ``nxt`` (backwards, the next the forward march left
    non-empty) at its first (forwards) or last step, or ``-1`` when none is left;
    returns the next ray to hand out."""
    n_rays = j_lo.size
    while nxt < n_rays and sign < 0 and j_lo[nxt] > j_hi[nxt]:
        nxt += 1
    if nxt < n_rays:
        ray[k], at[k] = nxt, j_lo[nxt] if sign > 0 else j_hi[nxt]
        return nxt + 1
    ray[k] = -1
    return nxt


@numba.njit(cache=True, nogil=True)
def _march(
    o, d, k_first, k_dir, dt, delta, reach, top, block, distance, dist_max, j_lo, j_hi
):  # pragma: no cover
    fblock, exact, inv_block = _block_rule(block)
    nb1, nb2, dist = distance.shape[1], distance.shape[2], distance.ravel()
    top0, top1, top2 = top[0], top[1], top[2]
    one_d, one_e = d.shape[0] == 1, delta.shape[0] == 1
    leap_of = _leap_table(dist_max if one_e else -1, block, reach[0])
    # Each ray's march is one serial chain of float operations: ``_LANES`` rays march at
    # once, a step each in turn, so the processor overlaps their chains; a lane whose ray
    # is done takes the next (backwards, the next ray the forward march left non-empty).
    ray, at = np.full(_LANES, -1, np.int64), np.zeros(_LANES, np.int64)
    for sign in (1, -1):
        nxt = busy = 0
        for k in range(_LANES):
            nxt = _take_next(k, nxt, sign, ray, at, j_lo, j_hi)
            busy += ray[k] >= 0
        while busy:
            for k in range(_LANES):
                r = ray[k]
                if r < 0:
                    continue
                dr = 0 if one_d else r
                er = 0 if one_e else r
                s0, s1, s2 = sign * delta[er, 0], sign * delta[er, 1], sign * delta[er, 2]
                j = at[k]
                t = (k_first + k_dir * j) * dt
                p0, p1, p2 = o[r, 0] + t * d[dr, 0], o[r, 1] + t * d[dr, 1], o[r, 2] + t * d[dr, 2]
                if exact:
                    i0 = np.int64(min(max(p0, 0.0), top0) * inv_block)
                    i1 = np.int64(min(max(p1, 0.0), top1) * inv_block)
                    i2 = np.int64(min(max(p2, 0.0), top2) * inv_block)
                else:
                    i0 = np.int64(_floor_divide(min(max(p0, 0.0), top0), fblock))
                    i1 = np.int64(_floor_divide(min(max(p1, 0.0), top1), fblock))
                    i2 = np.int64(_floor_divide(min(max(p2, 0.0), top2), fblock))
                c = dist[(i0 * nb1 + i1) * nb2 + i2]
                done = c <= 0
                if not done:
                    b0, b1, b2 = np.float64(i0), np.float64(i1), np.float64(i2)
                    if c == 1:
                        # ``(c - 1) block - 1e-6 < 0``: the distance's leap is below one
                        # step, so the leap is to the first sample out of the block.
                        skip = 1.0
                        go = True
                    else:
                        a_max = _axis_max(s0, s1, s2)
                        s_max = (s0, s1, s2)[a_max]
                        if one_e:
                            skip = leap_of[c]
                        else:
                            skip = math.floor(((c - 1) * block - 1e-6) / reach[er])
                        bound = (
                            _face(s_max, (p0, p1, p2)[a_max], (b0, b1, b2)[a_max], block)
                            if abs(s_max) > _TINY
                            else np.inf
                        )
                        go = not (
                            skip >= 1.0 and bound < np.inf and math.ceil(bound - 1e-6) <= skip
                        )
                    if go:
                        along = np.inf
                        if abs(s0) > _TINY:
                            along = min(along, _face(s0, p0, b0, block))
                        if abs(s1) > _TINY:
                            along = min(along, _face(s1, p1, b1, block))
                        if abs(s2) > _TINY:
                            along = min(along, _face(s2, p2, b2, block))
                        skip = max(max(skip, math.ceil(along - 1e-6)), 1.0)
                    j += sign * np.int64(skip)
                    at[k] = j
                    done = not (j <= j_hi[r] and j >= j_lo[r])
                if done:
                    if sign > 0:
                        j_lo[r] = j if j <= j_hi[r] else j_hi[r] + 1
                    else:
                        j_hi[r] = j
                    nxt = _take_next(k, nxt, sign, ray, at, j_lo, j_hi)
                    busy -= ray[k] < 0
