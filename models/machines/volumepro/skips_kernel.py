"""VolumePro 1000's per-slice beam skipping (rule 6), compiled (numba).

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rule 6 (clock groups of live rays,
#      mini-blocks of live cells); docs/transaction.md (the VolumePro 1000 event model).

:func:`frame_skips` is the compiled loop of
:func:`models.machines.volumepro.vp1000_transaction.beam_skips`, every sample slice in one
call: :func:`plan_step_cells` forms each planned sample's position from the shear-image
plan's ray terms itself (the compiled walker's floats,
:func:`models.fused_steps.plan_positions`, without per-sample position arrays; all the
active rays' in one branch-free, vectorised loop), then which cells hold a live sample
(each beam's clock groups holding one), the live samples and the busiest pipeline (each
sample's lane is the module ``(q + a + b) mod P`` of its nearest voxel,
:func:`~models.machines.volumepro.lanes.sample_lanes`' rule), and the cells the memory
sequencer reads for (alive ``lag`` slices earlier); each slab's cells are OR-ed over the
slices whose window holds it and its mini-blocks read once (:func:`union_blocks`,
:func:`~models.machines.volumepro.timing.mini_blocks_read`'s rule).  The same
floating-point operations as the NumPy form (``floor``, a subtraction, a comparison with
1/2), so the same integers; the NumPy form stays as the reference (``beam_skips(...,
compiled=False)``, compared by ``tests/models/test_transaction_vp1000.py``).

The cycle machine's side: :func:`slice_cells` (rule 6 at one sample slice of
:meth:`SlabMachine._live_cells`: clock groups and the mini-blocks read) and
:func:`beam_needs` (each processed beam's last delivery and each delivery's last reader,
:func:`~models.machines.volumepro.timing.timing_inputs`), their NumPy forms kept for the
unit chain (tests/models/test_slice_loads.py, tests/models/test_cycle_fused.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "PACK_LIMIT",
    "beam_needs",
    "cell_blocks",
    "active_rays",
    "frame_skips",
    "plan_step_cells",
    "slice_cells",
    "union_blocks",
]


#: Volume extent (voxels along an axis) below which :func:`plan_step_cells` packs a
#: ray's cell and lane sum in one word (21 bits each); larger volumes take the NumPy form.
PACK_LIMIT = 1 << 20


@numba.njit(cache=True, nogil=True)
def _cell(p: float, n: int) -> int:
    """The voxel cell ``floor(p)`` clamped to ``0 .. n - 1``."""
    return int(min(max(math.floor(p), 0.0), n - 1.0))


@numba.njit(cache=True, nogil=True)
def _nearest(p: float, n: int) -> int:
    """The nearest voxel ``floor(p) + (p - floor(p) >= 1/2)`` clamped to ``0 .. n - 1``."""
    c = math.floor(p)
    v = int(c) + (1 if p - c >= 0.5 else 0)
    return min(max(v, 0), n - 1)


@numba.njit(cache=True, nogil=True)
def _packed(pa, pb, fa_hi, fb_hi):
    """A sample's cell ``a``, ``b`` and lane sum ``na + nb`` (nearest voxels) at in-slice
    position ``pa``, ``pb``, packed in one word (21 bits each, :data:`PACK_LIMIT`)."""
    fa, fb = np.floor(pa), np.floor(pb)
    # Converted through int32 (exact: every value is below PACK_LIMIT): the machine has
    # no vector double -> int64 conversion without AVX-512, so ``int()`` kept the
    # position loop scalar; double -> int32 vectorises (~15 % of frame_skips).
    ca = np.int64(np.int32(min(max(fa, 0.0), fa_hi)))
    cb = np.int64(np.int32(min(max(fb, 0.0), fb_hi)))
    na = min(max(fa + (1.0 if pa - fa >= 0.5 else 0.0), 0.0), fa_hi)
    nb = min(max(fb + (1.0 if pb - fb >= 0.5 else 0.0), 0.0), fb_hi)
    return (ca << 42) | (cb << 21) | np.int64(np.int32(na + nb))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def plan_step_cells(
    j, ss, terms, join, j_lo, j_hi, last, dims, P, lag, rays, cells, groups, cost_row, uniform
):
    """One sample slice ``j`` of rule 6, straight from a shear-image plan's rays.

    Parameters
    ----------
    j : int
        The slice.
    ss : float
        The plan's supersampling.
    terms, join : ndarray
        float64 ``(8, rays)``: the plan rays' position terms, and int64 the rays with
        samples in join order (ascending ``j_lo``), both
        :func:`models.fused_steps.position_terms`' (no reordered copy of the terms).
    j_lo, j_hi : ndarray
        int64 per ray (join order): its first and last step.
    last : ndarray
        int64 per ray (join order), its last live step; empty: no ray stops.
    dims : tuple
        ``(n_k, n_a, n_b)``: the volume's extent along the principal axis, the beams
        and along a beam.
    P, lag : int
        Pipelines (cells per clock group); the sequencer's lag in slices.
    rays : ActiveRays
        The rays joined so far and not yet compacted away, kept between slices
        (:func:`active_rays` before the first).
    cells : ndarray
        uint8 ``n_a n_b`` (flat, zero on entry): 1 at the cells the memory reads for.
    groups : ndarray
        uint8 ``n_a ceil(n_b / P) P`` (flat, zero on entry): 1 at the cells holding a
        live sample, each beam's clock groups holding one counted into ``cost_row`` (its
        clocks).
    uniform : bool
        Whether rows 0, 1, 3, 5 and 7 of ``terms`` (step origin, sign and the direction)
        are the same for every ray (a parallel view): then only rows 2, 4 and 6 are read
        a ray (the same floats).

    Returns
    -------
    (int, int, int)
        Planned samples, live samples, and the busiest pipeline's.

    Each sample's position is :func:`models.fused_steps.plan_positions`' (the walker's
    ``_step``, shear-image: the same terms and operations, so the same floats), its
    cell and nearest voxel those of the NumPy form (``floor``, a subtraction, a
    comparison with 1/2, clamped: integers exact in float64), so the same integers.  The
    positions of all active rays are formed in one branch-free loop (vectorised), then
    marked.  A sample's pipeline is ``(q + a + b) mod P`` for the slice's voxel slice
    ``q`` (:func:`~models.machines.volumepro.lanes.sample_lanes`): counting ``(a + b)
    mod P`` instead permutes the lanes, so the busiest holds as many samples.
    """
    at, ints, cursor = rays
    n_a, n_b = dims[1], dims[2]
    C = -(-n_b // P)
    CP = C * P
    count, nxt = cursor[0], cursor[1]
    while nxt < j_lo.shape[0] and j_lo[nxt] <= j:
        for r in range(8):  # element by element, not a column view a ray
            at[r, count] = terms[r, join[nxt]]
        ints[0, count] = j_hi[nxt]
        ints[1, count] = last[nxt] if last.shape[0] > 0 else j_hi[nxt]
        count += 1
        nxt += 1
    j_ss = np.float64(j) / ss
    mask = P - 1 if P & (P - 1) == 0 else -1  # a power of two: the lane by a mask
    fa_hi, fb_hi = n_a - 1.0, n_b - 1.0
    if uniform and count:  # a parallel view: rows 0, 1, 3, 5, 7 the same for every ray
        pk, dk, da, db = at[0, 0] + at[1, 0] * j_ss, at[3, 0], at[5, 0], at[7, 0]
        for k in range(count):  # three rows read a ray, not eight (its rays stay in L2)
            along = (pk - at[2, k]) / dk
            ints[2, k] = _packed(at[4, k] + along * da, at[6, k] + along * db, fa_hi, fb_hi)
    for k in range(0 if uniform else count):  # every active ray's cell and lane
        along = (at[0, k] + at[1, k] * j_ss - at[2, k]) / at[3, k]
        ints[2, k] = _packed(at[4, k] + along * at[5, k], at[6, k] + along * at[7, k], fa_hi, fb_hi)
    # Four histograms of the lanes, ray k counted in histogram k mod 4: neighbouring
    # rays often share a lane, and one histogram chained each increment on the last.
    lanes4 = np.zeros(4 * P, dtype=np.int64)
    m, live, dead = 0, 0, 0
    # Row views and unsigned cell indices: numba emits no negative-index wrap a read.
    # Each ray's cell a, b and lane sum packed in one word (21 bits each, PACK_LIMIT):
    # a third of the bytes the position loop writes and this one reads back.
    hi_, last_, packed = ints[0], ints[1], ints[2]
    low = np.uint64((1 << 21) - 1)
    ub, ucp = np.uint64(n_b), np.uint64(CP)
    umask = np.uint64(mask if mask >= 0 else 0)
    for k in range(count):
        if hi_[k] < j:
            dead += 1
            continue
        m += 1
        v = np.uint64(packed[k])
        a, b = v >> np.uint64(42), (v >> np.uint64(21)) & low
        cell = a * ub + b
        lst = last_[k]
        if lst >= j:
            cells[cell] = 1
            groups[a * ucp + b] = 1
            live += 1
            s = v & low
            off = np.uint64(k & 3) * np.uint64(P)
            if mask >= 0:
                lanes4[off + (s & umask)] += 1
            else:
                lanes4[off + s % np.uint64(P)] += 1
        elif j < lag or lst > j - lag:  # the sequencer read for rays alive lag slices earlier
            cells[cell] = 1
    if 8 * dead > count:  # compact, keeping the order
        kept = 0
        for i in range(count):
            if ints[0, i] >= j:  # element by element: a column view a ray was ~20 ns
                for r in range(8):
                    at[r, kept] = at[r, i]
                ints[0, kept], ints[1, kept] = ints[0, i], ints[1, i]
                kept += 1
        count = kept
    cursor[0], cursor[1] = count, nxt
    if live:
        _count_groups(groups, n_a, C, P, cost_row)
    lanes = lanes4[:P] + lanes4[P : 2 * P] + lanes4[2 * P : 3 * P] + lanes4[3 * P :]
    return m, live, lanes.max()


@numba.njit(cache=True, nogil=True)
def _count_groups(held, n_a, C, P, cost_row):
    """Per beam ``a``, its clock groups of ``P`` cells holding a marked cell of ``held``
    (uint8 ``n_a C P``, flat) into ``cost_row``: a group is one machine word when ``P``
    is 8."""
    if P == 8:
        words = held.view(np.uint64)
        for a in range(n_a):
            n = 0
            for c in range(a * C, a * C + C):
                n += 1 if words[c] else 0
            cost_row[a] = n
        return
    for a in range(n_a):
        n = 0
        for c in range(a * C, a * C + C):
            for p in range(c * P, c * P + P):
                if held[p]:
                    n += 1
                    break
        cost_row[a] = n


def active_rays(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`plan_step_cells`' state for ``n`` rays: their terms, per ray its last step,
    last live step, and cell ``a``, ``b`` and lane sum packed in one word; the active
    count and next ray to join.  Allocated by NumPy, which asks for huge pages (the
    first touch of a fresh array allocated in numba costs about four times as much, on
    4 KiB pages)."""
    return (
        np.zeros((8, max(n, 1))),
        np.zeros((3, max(n, 1)), dtype=np.int64),
        np.zeros(2, dtype=np.int64),
    )


@numba.njit(cache=True, nogil=True)
def frame_skips(
    ss,
    terms,
    join,
    j_lo,
    j_hi,
    last,
    dims,
    P,
    lag,
    windows,
    rays,
    cost,
    live,
    busiest,
    needed,
    uniform,
):
    """Rule 6 at every sample slice of a shear-image plan (:func:`plan_step_cells` slice
    after slice), and the mini-blocks read.

    ``windows`` int64 ``(n_steps, 2)``: the slabs ``lo .. hi`` holding each slice's voxel
    window; ``cost`` ``(n_steps, n_a)``, ``live`` and ``busiest`` ``(n_steps,)`` (zeros)
    get each slice's per-beam clocks, live samples and busiest pipeline's samples;
    ``needed`` ``(slabs, ceil(n_a / 2), ceil(n_b / 2))`` (False) the mini-blocks read.
    ``rays``: :func:`active_rays` of the plan's rays.  The other arguments are
    :func:`plan_step_cells`'.  Each slab's cells are OR-ed over
    the slices with planned samples whose window holds it, and its mini-blocks read once
    (:func:`union_blocks`) when the windows have moved past it: the mini-blocks of a
    union of cells are the union of theirs.
    """
    n_steps = cost.shape[0]
    n_a, n_b = dims[1], dims[2]
    cells = np.zeros(n_a * n_b, dtype=np.uint8)
    groups = np.zeros(n_a * -(-n_b // P) * P, dtype=np.uint8)
    span = 1
    for j in range(n_steps):
        span = max(span, windows[j, 1] - windows[j, 0] + 1)
    unions = np.zeros((span + 1, n_a * n_b), dtype=np.uint8)
    slab_of = np.full(span + 1, -1, dtype=np.int64)  # the open slab in each union
    for j in range(n_steps):
        m, live[j], busiest[j] = plan_step_cells(
            j,
            ss,
            terms,
            join,
            j_lo,
            j_hi,
            last,
            dims,
            P,
            lag,
            rays,
            cells,
            groups,
            cost[j],
            uniform,
        )
        if m == 0:
            continue
        lo, hi = windows[j, 0], windows[j, 1]
        for i in range(span + 1):  # read the slabs the windows have moved past
            if slab_of[i] >= 0 and not lo <= slab_of[i] <= hi:
                union_blocks(unions[i].reshape(n_a, n_b), needed[slab_of[i]])
                slab_of[i] = -1
        for s in range(lo, hi + 1):
            i = 0
            while i <= span and slab_of[i] != s:
                i += 1
            if i > span:  # a free union
                i = 0
                while slab_of[i] >= 0:
                    i += 1
                slab_of[i] = s
                unions[i][:] = 0
            union = unions[i]
            for x in range(cells.shape[0]):  # a flat loop: LLVM vectorises it
                union[x] |= cells[x]
        cells[:] = 0
        groups[:] = 0
    for i in range(span + 1):  # the slabs still open
        if slab_of[i] >= 0:
            union_blocks(unions[i].reshape(n_a, n_b), needed[slab_of[i]])


@numba.njit(cache=True, nogil=True)
def union_blocks(cells, blocks):
    """OR into ``blocks`` ``(ceil(n_a / 2), ceil(n_b / 2))`` the mini-blocks holding a
    voxel that a marked cell of ``cells`` ``(n_a, n_b)`` reads:
    :func:`~models.machines.volumepro.timing.mini_blocks_read`'s rule (cell ``(a, b)``
    reads voxel rows ``a - 1 .. a + 2`` and columns ``b - 1 .. b + 2``), as rows then
    columns: mini-block ``(u, v)`` is read when a cell of rows ``2u - 2 .. 2u + 2`` and
    columns ``2v - 2 .. 2v + 2`` (clamped) is marked."""
    n_a, n_b = cells.shape
    flat = cells.reshape(-1)  # flat loops: LLVM vectorises them
    rows = np.zeros(n_b, dtype=np.uint8)
    pairs = np.zeros(blocks.shape[1], dtype=np.uint8)
    for u in range(blocks.shape[0]):
        rows[:] = 0
        for a in range(max(2 * u - 2, 0), min(2 * u + 2, n_a - 1) + 1):
            row = flat[a * n_b : (a + 1) * n_b]
            for b in range(n_b):
                rows[b] |= row[b]
        for v in range(n_b // 2):  # columns 2v, 2v + 1
            pairs[v] = rows[2 * v] | rows[2 * v + 1]
        if n_b % 2:
            pairs[n_b // 2] = rows[n_b - 1]
        for v in range(blocks.shape[1]):  # columns 2v - 2 .. 2v + 2
            hit = pairs[v] | (pairs[v - 1] if v else 0)
            if hit or (2 * v + 2 < n_b and rows[2 * v + 2]):
                blocks[u, v] = True


@numba.njit(cache=True, nogil=True)
def slice_cells(pa, pb, live, known, P, n_b, cells, cost_row, blocks):
    """Rule 6 at one sample slice of the cycle machine (:meth:`SlabMachine._live_cells`),
    its samples at in-slice positions ``pa``, ``pb``: ``cost_row`` each beam's clock
    groups of ``P`` cells holding a sample of a ``live`` ray, ``blocks`` ``(ceil(n_a / 2),
    ceil(n_b / 2))`` the mini-blocks holding a voxel that a cell of a ``known`` ray reads
    (rows ``a - 1 .. a + 2``, columns ``b - 1 .. b + 2``: the NumPy form's
    :func:`~models.machines.volumepro.timing.mini_blocks_read`).  ``cells`` ``(n_a, C P)``
    is scratch, overwritten."""
    n_a = cells.shape[0]
    C = cells.shape[1] // P
    cells[:] = False
    for i in range(pa.shape[0]):
        if live[i]:
            cells[_cell(pa[i], n_a), _cell(pb[i], n_b)] = True
    for a in range(n_a):
        groups = 0
        for c in range(C):
            for p in range(P):
                if cells[a, c * P + p]:
                    groups += 1
                    break
        cost_row[a] = groups
    for i in range(pa.shape[0]):
        if known[i]:
            cells[_cell(pa[i], n_a), _cell(pb[i], n_b)] = True
    cell_blocks(cells, n_b, blocks)


@numba.njit(cache=True, nogil=True)
def cell_blocks(cells, n_b, blocks):
    """:func:`~models.machines.volumepro.timing.mini_blocks_read` of ``cells[:, :n_b]``
    into ``blocks`` ``(ceil(n_a / 2), ceil(n_b / 2))``, overwritten: the mini-blocks
    holding voxel rows ``a - 1 .. a + 2`` and columns ``b - 1 .. b + 2`` of a marked cell
    ``(a, b)``."""
    n_a = cells.shape[0]
    blocks[:] = False
    for a in range(n_a):
        u0, u1 = max(a - 1, 0) // 2, min(a + 2, n_a - 1) // 2
        for b in range(n_b):
            if cells[a, b]:
                v0, v1 = max(b - 1, 0) // 2, min(b + 2, n_b - 1) // 2
                for u in range(u0, u1 + 1):
                    for v in range(v0, v1 + 1):
                        blocks[u, v] = True


@numba.njit(cache=True, nogil=True)
def beam_needs(index, rows, s0, s1, n_a, first, need, free_after):
    """The deliveries of one sample slice's processed beams (the windowed rules' reads,
    :func:`~models.machines.volumepro.timing.timing_inputs`): beam ``i`` (voxel row
    ``rows[i]``, beam number ``first + i``) reads mini-block beams ``u`` of ``(rows[i] -
    1) // 2 .. (rows[i] + 2) // 2`` (clamped) in slabs ``s0 .. s1``, whose delivery
    numbers are ``index[slab, u]`` (-1: not read); ``need[i]`` the last of them (-1:
    none) and ``free_after[d]`` raised to the last beam reading delivery ``d``."""
    for i in range(rows.shape[0]):
        r = rows[i]
        u_lo, u_hi = max(r - 1, 0) // 2, min(r + 2, n_a - 1) // 2
        last = -1
        for d in range(3):
            u = min(u_lo + d, u_hi)
            for slab in range(s0, s1 + 1):
                g = index[slab, u]
                if g > last:
                    last = g
                if g >= 0 and free_after[g] < first + i:
                    free_after[g] = first + i
        need[i] = last
