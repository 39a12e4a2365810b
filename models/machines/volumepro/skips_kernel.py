"""VolumePro 1000's per-slice beam skipping (rule 6) at one sample slice, compiled (numba).

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rule 6 (clock groups of live rays,
#      mini-blocks of live cells); docs/transaction.md (the VolumePro 1000 event model).

:func:`step_cells` is the loop body of
:func:`models.machines.volumepro.vp1000_transaction.beam_skips` for one sample slice: which
cells hold a live sample, each beam's clock groups, the live samples and the busiest
pipeline (each sample's lane is the module ``(q + a + b) mod P`` of its nearest voxel,
:func:`~models.machines.volumepro.lanes.sample_lanes`' rule), then the cells the
memory sequencer reads for (alive ``lag`` slices earlier).  The same floating-point
operations as the NumPy form (``floor``, a subtraction, a comparison with 1/2), so the same
integers; the NumPy form stays as the reference
(``beam_skips(..., compiled=False)``, compared by ``tests/models/test_transaction_vp1000.py``).

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

__all__ = ["beam_needs", "cell_blocks", "slice_cells", "step_cells"]


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
def step_cells(zyx, axes, shape, P, last, j, lag, cells, cost_row):
    """One sample slice ``j`` of rule 6.

    Parameters
    ----------
    zyx : ndarray
        float64 ``(n, 3)``: the slice's sample positions.
    axes, shape : ndarray
        int64 ``(k, a, b)`` axes and the volume's shape ``(z, y, x)``.
    P : int
        Pipelines (cells per clock group).
    last : ndarray
        int64 per sample, its ray's last live step; empty: no ray stops.
    j, lag : int
        The slice, and the sequencer's lag in slices.
    cells : ndarray
        bool ``(n_a, C P)``: overwritten with the cells the memory reads for.
    cost_row : ndarray
        int64 ``(n_a,)``: overwritten with each beam's clock groups holding a live sample.

    Returns
    -------
    (int, int)
        Live samples, and the busiest pipeline's.
    """
    kp, a_ax, b_ax = axes[0], axes[1], axes[2]
    n_k, n_a, n_b = shape[kp], shape[a_ax], shape[b_ax]
    stops = last.shape[0] > 0
    cells[:] = False
    lanes = np.zeros(P, dtype=np.int64)
    live, q = 0, -1
    for i in range(zyx.shape[0]):
        if stops and last[i] < j:
            continue
        if q < 0:  # every sample of a slice lies on its sample slice
            q = _cell(zyx[i, kp] + 0.5, n_k)
        cells[_cell(zyx[i, a_ax], n_a), _cell(zyx[i, b_ax], n_b)] = True
        live += 1
        lane = (q + _nearest(zyx[i, a_ax], n_a) + _nearest(zyx[i, b_ax], n_b)) % P
        lanes[lane] += 1
    C = cells.shape[1] // P
    for a in range(n_a):
        groups = 0
        for c in range(C):
            for p in range(P):
                if cells[a, c * P + p]:
                    groups += 1
                    break
        cost_row[a] = groups
    if stops:  # the sequencer read for rays alive ``lag`` slices earlier (a superset)
        for i in range(zyx.shape[0]):
            if j < lag or last[i] > j - lag:
                cells[_cell(zyx[i, a_ax], n_a), _cell(zyx[i, b_ax], n_b)] = True
    return live, lanes.max()


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
