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

__all__ = ["split_streams"]


@numba.njit(cache=True, nogil=True)
def split_streams(module, bank, row, spans, needed, wpv, modules):
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
    wpv, modules : int
        Bursts per mini-block; memory modules.

    Returns
    -------
    (ndarray, ndarray, ndarray)
        ``per`` int64 ``(modules, chunks)``: each chunk's bursts on each module; ``banks``
        and ``rows`` int64 ``(total,)``: module 0's stream, then module 1's, ..., each in
        read order.
    """
    n_mb = module.shape[2] // wpv
    skips = needed.shape[0] > 0
    nc = spans.shape[0]
    per = np.zeros((modules, nc), dtype=np.int64)
    for c in range(nc):  # pass 1: how many bursts of each chunk go to each module
        s = spans[c, 0]
        for u in range(spans[c, 1], spans[c, 2]):
            for m in range(n_mb):
                if skips and not needed[s, u, m]:
                    continue
                for w in range(m * wpv, m * wpv + wpv):
                    per[module[s, u, w], c] += 1
    start = np.zeros(modules, dtype=np.int64)
    for k in range(1, modules):
        start[k] = start[k - 1] + per[k - 1].sum()
    total = start[modules - 1] + per[modules - 1].sum()
    banks = np.empty(total, dtype=np.int64)
    rows = np.empty(total, dtype=np.int64)
    at = start.copy()
    for c in range(nc):  # pass 2: the bursts into their module's stream, in order
        s = spans[c, 0]
        for u in range(spans[c, 1], spans[c, 2]):
            for m in range(n_mb):
                if skips and not needed[s, u, m]:
                    continue
                for w in range(m * wpv, m * wpv + wpv):
                    k = module[s, u, w]
                    banks[at[k]] = bank[s, u, w]
                    rows[at[k]] = row[s, u, w]
                    at[k] += 1
    return per, banks, rows
