"""The VolumePro-family transaction model's chunk bursts split by module, compiled (numba).

# Ref: docs/transaction.md "The VolumePro 500 / EM-Cube event model" (the memory
#      process); models/machines/volumepro/chunk_reads.py (chunk_streams).

:func:`split_streams` walks every chunk's mini-block beams in read order (beam by beam,
the mini-blocks along the beam, a mini-block's bursts back to back), keeps the
mini-blocks read (all, or with skipping those a live cell needs) and writes each burst's
bank and row into its module's stream: the loop the NumPy form ran as boolean masks over
every slab's layout, once per module.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["beam_groups", "bursts_read", "live_spans", "split_streams"]


@numba.njit(cache=True, nogil=True)
def bursts_read(spans, needed, n_mb, wpv):
    """The bursts of the chunks ``spans`` (:func:`split_streams`) that are read."""
    total = 0
    for c in range(spans.shape[0]):
        s = spans[c, 0]
        for u in range(spans[c, 1], spans[c, 2]):
            if needed.shape[0] > 0:
                for m in range(n_mb):
                    total += wpv if needed[s, u, m] else 0
            else:
                total += n_mb * wpv
    return total


@numba.njit(cache=True, nogil=True)
def split_streams(module, bank, row, spans, needed, wpv, banks, rows):
    """Every chunk's bursts, split by module.

    Parameters
    ----------
    module, bank, row : ndarray
        ``(slabs, n_u, n_mb wpv)``: the layout of every burst of every slab's mini-block
        beams (:func:`models.machines.volumepro.chunk_reads.slab_layouts`).
    spans : ndarray
        int64 ``(chunks, 3)``: each chunk's slab and mini-block beams ``u_lo .. u_hi``
        (exclusive), in read order.
    needed : ndarray
        bool ``(slabs, n_u, n_mb)``: the mini-blocks read; empty: all of them.
    wpv : int
        Bursts per mini-block.
    banks, rows : ndarray
        int64 ``(modules, total)``, ``total`` the bursts read (:func:`bursts_read`):
        row ``k`` gets module ``k``'s stream in read order (its first ``per[k].sum()``
        entries; the rest is not written).  Allocated by the caller: NumPy asks the
        kernel for huge pages, which the first touch of a fresh array costs far less
        on than on 4 KiB ones (numba's own allocation).

    Returns
    -------
    ndarray
        ``per`` int64 ``(modules, chunks)``: each chunk's bursts on each module.
    """
    n_mb = module.shape[2] // wpv
    skips = needed.shape[0] > 0
    nc, modules = spans.shape[0], banks.shape[0]
    per = np.zeros((modules, nc), dtype=np.int64)
    if modules == 4:
        _split_four(module, bank, row, spans, needed, wpv, banks, rows, per)
        nc = 0  # done
    at = np.zeros(modules, dtype=np.int64)
    for c in range(nc):  # one pass: the bursts into their module's stream, in order
        s = spans[c, 0]
        for u in range(spans[c, 1], spans[c, 2]):
            for m in range(n_mb):
                if skips and not needed[s, u, m]:
                    continue
                for w in range(m * wpv, m * wpv + wpv):
                    k = module[s, u, w]
                    banks[k, at[k]] = bank[s, u, w]
                    rows[k, at[k]] = row[s, u, w]
                    at[k] += 1
        for k in range(modules):
            per[k, c] = at[k]
    for c in range(per.shape[1] - 1, 0, -1):
        for k in range(modules):
            per[k, c] -= per[k, c - 1]
    return per


@numba.njit(cache=True, nogil=True)
def _split_four(module, bank, row, spans, needed, wpv, banks, rows, per):
    """:func:`split_streams`' pass for four modules (VolumePro 1000), each stream's fill
    in a register rather than an array entry reloaded after every store (twice as fast);
    ``per`` gets the running fills after each chunk."""
    n_mb = module.shape[2] // wpv
    skips = needed.shape[0] > 0
    a0 = a1 = a2 = a3 = 0
    for c in range(spans.shape[0]):
        s = spans[c, 0]
        for u in range(spans[c, 1], spans[c, 2]):
            for m in range(n_mb):
                if skips and not needed[s, u, m]:
                    continue
                for w in range(m * wpv, m * wpv + wpv):
                    k, b, r = module[s, u, w], bank[s, u, w], row[s, u, w]
                    if k == 0:
                        banks[0, a0], rows[0, a0] = b, r
                        a0 += 1
                    elif k == 1:
                        banks[1, a1], rows[1, a1] = b, r
                        a1 += 1
                    elif k == 2:
                        banks[2, a2], rows[2, a2] = b, r
                        a2 += 1
                    else:
                        banks[3, a3], rows[3, a3] = b, r
                        a3 += 1
        per[0, c], per[1, c], per[2, c], per[3, c] = a0, a1, a2, a3


@numba.njit(cache=True, nogil=True)
def beam_groups(index, windows, spans, dims, band, first, groups, last):
    """One band's beam groups of every sample slice, in processing order, and each
    chunk's last reader (:meth:`~models.machines.volumepro.transaction.SlabTransaction.
    _schedule`'s loop).

    Parameters
    ----------
    index : ndarray
        int64 ``(slabs, chunks of a slab)``: the chunk number of each slab's ``k``-th
        chunk of the band (-1: not read).
    windows : ndarray
        int64 ``(n_steps, 2)``: the slabs ``lo .. hi`` holding each slice's voxel window.
    spans : tuple of ndarray
        ``(clocks, lo, hi)``, each int64 ``(n_steps, spans)``: each span of rows' clocks
        (0: every row skipped, no group) and its first and last row needing a chunk.
    dims : tuple
        ``(n_a, u0, U)``: the beams, the band's first mbb and the mbbs a chunk.
    band, first : int
        The band's number and its first group's.
    groups : ndarray
        int64 ``(>= n_steps (spans + 1), 4)``: gets ``(band, j, clocks, last chunk
        needed or -1)`` per group; a slice whose every span is skipped keeps one empty
        group.
    last : ndarray
        int64 per chunk: raised to the last group needing it.

    Returns
    -------
    int
        The next group's number.
    """
    clocks, span_lo, span_hi = spans
    n_a, u0, U = dims
    n_k = index.shape[1]
    g = first
    for j in range(clocks.shape[0]):
        s_lo, s_hi = windows[j, 0], windows[j, 1]
        start = g
        for si in range(clocks.shape[1]):
            if clocks[j, si] == 0:
                continue
            k_lo = (max(span_lo[j, si] - 1, 0) // 2 - u0) // U
            k_hi = min((min(span_hi[j, si] + 2, n_a - 1) // 2 - u0) // U, n_k - 1)
            need = -1
            for s in range(s_lo, s_hi + 1):
                for k in range(k_lo, k_hi + 1):
                    c = index[s, k]
                    if c >= 0:
                        need = max(need, c)
                        last[c] = g
            row = groups[g - first]
            row[0], row[1], row[2], row[3] = band, j, clocks[j, si], need
            g += 1
        if g == start:  # every beam of the slice skipped
            row = groups[g - first]
            row[0], row[1], row[2], row[3] = band, j, 0, -1
            g += 1
    return g


def live_spans(cost: np.ndarray, r0: np.ndarray, r1: np.ndarray):
    """Per sample slice and span ``r0[i] .. r1[i] - 1`` of rows (consecutive spans): the
    span's clocks (``cost`` summed) and its first and last row of nonzero cost
    (meaningful where the clocks are not 0), int64 ``(slices, spans)`` each."""
    start = int(r0[0])
    part = cost[:, start : int(r1[-1])]
    rows = np.arange(start, int(r1[-1]))
    local = r0 - start
    live = part > 0
    clocks = np.add.reduceat(part, local, axis=1)
    lo = np.minimum.reduceat(np.where(live, rows, rows[-1] + 1), local, axis=1)
    hi = np.maximum.reduceat(np.where(live, rows, -1), local, axis=1)
    return tuple(np.ascontiguousarray(v, dtype=np.int64) for v in (clocks, lo, hi))
