"""VolumePro 1000's per-slice beam skipping (rule 6) at one sample slice, compiled (numba).

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rule 6 (clock groups of live rays,
#      mini-blocks of live cells); docs/transaction.md (the VolumePro 1000 event model).

:func:`plan_step_cells` is the loop body of
:func:`models.machines.volumepro.vp1000_transaction.beam_skips` for one sample slice: it
forms each planned sample's position from the shear-image plan's ray terms itself (the
compiled walker's floats, :func:`models.fused_steps.plan_positions`, without per-sample
position arrays), then which cells hold a live sample (each beam's clock groups:
:func:`count_groups`), the live samples and the busiest pipeline (each sample's lane is
the module ``(q + a + b) mod P`` of its nearest voxel,
:func:`~models.machines.volumepro.lanes.sample_lanes`' rule), and the cells the memory
sequencer reads for (alive ``lag`` slices earlier).  The same floating-point operations
as the NumPy form (``floor``, a subtraction, a comparison with 1/2), so the same
integers; the NumPy form stays as the reference (``beam_skips(..., compiled=False)``,
compared by ``tests/models/test_transaction_vp1000.py``).

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

__all__ = ["beam_needs", "cell_blocks", "count_groups", "plan_step_cells", "slice_cells"]


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


@numba.njit(cache=True, nogil=True, error_model="numpy")
def plan_step_cells(
    j, ss, terms, j_lo, j_hi, last, axes, shape, P, lag, active, cursor, cells, held
):
    """One sample slice ``j`` of rule 6, straight from a shear-image plan's rays.

    Parameters
    ----------
    j : int
        The slice.
    ss : float
        The plan's supersampling.
    terms : ndarray
        float64 ``(9, n)``: the plan rays with samples in join order (ascending
        ``j_lo``), their position terms (:func:`models.fused_steps.position_terms`).
    j_lo, j_hi : ndarray
        int64 per ray (join order): its first and last step.
    last : ndarray
        int64 per ray (join order), its last live step; empty: no ray stops.
    axes, shape : ndarray
        int64 ``(k, a, b)`` axes and the volume's shape ``(z, y, x)``.
    P, lag : int
        Pipelines (cells per clock group); the sequencer's lag in slices.
    active, cursor : ndarray
        int64 scratch kept between slices (zeros before the first): the active rays
        (ascending), and their count and the next ray to join.
    cells : ndarray
        bool ``(n_a, C P)``: overwritten with the cells the memory reads for.
    held : ndarray
        bool ``(n_a, C P)``: overwritten with the cells holding a live sample (each
        beam's clock groups holding one are its clocks: :func:`count_groups`).

    Returns
    -------
    (int, int, int)
        Planned samples, live samples, and the busiest pipeline's.

    Each sample's position is :func:`models.fused_steps.plan_positions`' (the walker's
    ``_step``, shear-image: the same terms, operations and ray order, so the same floats
    and the same first live sample), its cells, clock groups and lane those of the
    NumPy form (``floor``, a subtraction, a comparison with 1/2; positions are finite,
    so clamping the integer is clamping the float), so the same integers, without
    per-sample position arrays.
    """
    kp, a_ax, b_ax = axes[0], axes[1], axes[2]
    n_k, n_a, n_b = shape[kp], shape[a_ax], shape[b_ax]
    stops = last.shape[0] > 0
    count, nxt = cursor[0], cursor[1]
    while nxt < j_lo.shape[0] and j_lo[nxt] <= j:
        active[count] = nxt
        count += 1
        nxt += 1
    cells[:] = False
    held[:] = False
    lanes = np.zeros(P, dtype=np.int64)
    mask = P - 1 if P & (P - 1) == 0 else -1  # a power of two: the lane by a mask
    j_ss = np.float64(j) / ss
    m, live, q, dead = 0, 0, -1, 0
    for k in range(count):
        r = active[k]
        if j_hi[r] < j:
            dead += 1
            continue
        pk = terms[0, r] + terms[1, r] * j_ss
        along = (pk - terms[2, r]) / terms[3, r]
        pa = terms[4, r] + along * terms[5, r]
        pb = terms[6, r] + along * terms[7, r]
        m += 1
        fa, fb = math.floor(pa), math.floor(pb)
        ca = min(max(fa, 0), n_a - 1)
        cb = min(max(fb, 0), n_b - 1)
        lst = last[r] if stops else j
        if lst >= j:
            if q < 0:  # every sample of a slice lies on its sample slice
                q = _cell(pk + 0.5, n_k)
            cells[ca, cb] = True
            held[ca, cb] = True
            live += 1
            na = min(max(fa + (1 if pa - fa >= 0.5 else 0), 0), n_a - 1)
            nb = min(max(fb + (1 if pb - fb >= 0.5 else 0), 0), n_b - 1)
            lane = q + na + nb
            lanes[lane & mask if mask >= 0 else lane % P] += 1
        elif j < lag or lst > j - lag:  # the sequencer read for rays alive lag slices earlier
            cells[ca, cb] = True
    if 8 * dead > count:  # compact, keeping the order
        kept = 0
        for t in range(count):
            if j_hi[active[t]] >= j:
                active[kept] = active[t]
                kept += 1
        count = kept
    cursor[0], cursor[1] = count, nxt
    return m, live, lanes.max()


def count_groups(held: np.ndarray, P: int) -> np.ndarray:
    """Per beam (row of ``held``, ``(n_a, C P)`` bool), its clock groups of ``P`` cells
    holding a marked cell: a group is one machine word when ``P`` is 1, 2, 4 or 8."""
    word = {1: np.uint8, 2: np.uint16, 4: np.uint32, 8: np.uint64}.get(P)
    if word is not None:
        return np.count_nonzero(held.view(word), axis=1)
    return held.reshape(held.shape[0], -1, P).any(axis=2).sum(axis=1)


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
