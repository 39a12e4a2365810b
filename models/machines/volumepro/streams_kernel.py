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

__all__ = ["bursts_read", "split_streams"]


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
    for c in range(nc - 1, 0, -1):
        for k in range(modules):
            per[k, c] -= per[k, c - 1]
    return per
