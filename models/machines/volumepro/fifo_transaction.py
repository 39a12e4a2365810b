"""The transaction rung's beam groups under the slice-FIFO rules 3', 5' (docs/cycle.md):
the event model's periods, chunk by chunk.

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rules 3', 5', 8'; architectures.md
#      1.3 items 2, 4-5 (slice and beam delay FIFOs), 3 (VolumePro 500), 9.1-9.2.

Written from the rules, not from the cycle rung's code
(:mod:`models.machines.volumepro.fifo_timing`): the rules' reach of a sample slice is
taken from its float position (the cycle rung's from the quantised weight), and a group of
``2 U`` rows waits for every chunk holding one of its rows and frees the chunks no later
group reads (the cycle rung: each beam, its own mini-block beam).
"""

from __future__ import annotations

import numpy as np

from models.machines.common.slice_order import slice_position

__all__ = ["chunk_index", "fifo_schedule", "reach_of"]


def reach_of(txn, j: int) -> int:
    """The voxel slice (processing order) furthest along that sample slice ``j`` uses:
    its upper tap (the lower at a fraction of 0), plus one for the central difference's
    next sample, clipped."""
    n = txn.n_k
    p = min(max(slice_position(txn.plan, j, txn.forward), 0.0), n - 1.0)
    i0 = int(min(np.floor(p), max(n - 2, 0)))
    frac = p - i0
    if txn.forward:
        return min((i0 + 1 if frac > 0 else i0) + 1, n - 1)
    return n - 1 - max((i0 if frac < 1 else i0 + 1) - 1, 0)


def _period(txn, index, band, key, p, groups, needs) -> None:
    """One period's groups: reading voxel slice ``p`` (processing order; -1: none)."""
    bi, u0, spans = band
    vol = p if txn.forward else txn.n_k - 1 - p
    for r0, r1 in spans:
        ids = []
        if p >= 0:
            ks = range((r0 // 2 - u0) // txn.U, ((r1 - 1) // 2 - u0) // txn.U + 1)
            ids = [index[bi, vol // 2, k] for k in ks if (bi, vol // 2, k) in index]
        groups.append((bi, key, (r1 - r0) * txn.C, max(ids, default=-1)))
        needs.append(ids)


def fifo_schedule(txn, n_steps: int, chunks, index):
    """Beam groups ``(band, key, clocks, last chunk needed)`` in processing order, and each
    chunk's last group: per band, a period per sample slice (``key = j``) reading the next
    voxel slice its reach needs, preceded by read-only periods (``key = -1 - slice``) for
    the slices it needs before; each period's groups read the band's rows
    ``a0 - 1 .. a1 + 1``, ``2 U`` at a time, ``C`` clocks a row."""
    groups, needs = [], []
    for bi, (a0, a1) in enumerate(txn.bands):
        r_lo, r_hi = max(a0 - 1, 0), min(a1 + 1, txn.n_a - 1)
        spans = [(r, min(r + 2 * txn.U, r_hi + 1)) for r in range(r_lo, r_hi + 1, 2 * txn.U)]
        band = (bi, r_lo // 2, spans)
        read = 0
        for j in range(n_steps):
            reach = reach_of(txn, j)
            while read < reach:
                _period(txn, index, band, -1 - read, read, groups, needs)
                read += 1
            _period(txn, index, band, j, read if read == reach else -1, groups, needs)
            read += read == reach
    free_after = np.full(len(chunks), -1, dtype=np.int64)
    for g, ids in enumerate(needs):
        free_after[ids] = g
    return groups, free_after


def chunk_index(grids: list[np.ndarray]) -> dict[tuple[int, int, int], int]:
    """Chunk number by ``(band, slab, k)`` from the bands' grids (-1: not read)."""
    index = {}
    for bi, grid in enumerate(grids):
        slab, k = np.nonzero(grid >= 0)
        for s, q, c in zip(slab.tolist(), k.tolist(), grid[slab, k].tolist(), strict=True):
            index[bi, s, q] = c
    return index
