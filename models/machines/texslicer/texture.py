"""The texture units' memory side: the texel lines each slice reads.

# Ref: docs/architectures.md ("texture-slicer"); models/units/interp.py (the weights).

A 2-D stack's slice is one texture: the bilinear unit reads the four texels of the
sample's cell in that slice (the sample lies on it: its weight along the stack's axis is
zero).  A 3-D texture's trilinear unit reads all eight.  The units interpolate with the
datapath's interpolator formats (``[formats] interp``;
:class:`models.machines.common.taps.TapSamples`), so the image is the functional rung's
bit for bit; what is the machine's own is which texels are read from memory.
Texture memory is tiled in lines of ``[buffers] texture_line`` texels (z, y, x); the
texture cache keeps the lines one slice reads, so each line is fetched once per slice
(the cache is flushed between slices [I]).
"""

from __future__ import annotations

import itertools

import numpy as np

from models.units import interp as interp_unit

__all__ = ["TexelLines"]

NONE = np.iinfo(np.int64).max  # no fragment has read the line yet


class TexelLines:
    """Which texel lines each slice reads, and the first fragment (rasterization order)
    reading each: ``lines(taps)`` for one slice's samples.  ``axis``: a 2-D stack's axis
    (its units read the sample's slice only: the cell's far side along the axis when the
    sample lies there), None for a 3-D texture."""

    def __init__(self, shape: tuple[int, int, int], line: tuple[int, int, int], axis: int | None):
        self.axis = axis
        self.hi = np.asarray(shape, dtype=np.int64)[:, None] - 1
        L = np.asarray(line, dtype=np.int64)
        if axis is not None:  # a 2-D slice is one texel deep along its stack's axis
            L[axis] = 1
        self.L = L[:, None]
        self.counts = -(-np.asarray(shape, dtype=np.int64) // L)
        self.offsets = [
            np.asarray(d, dtype=np.int64)[:, None]
            for d in itertools.product(*[(0,) if a == axis else (0, 1) for a in range(3)])
        ]
        # Per line: the first fragment reading it in the current slice (reset after each).
        self._first = np.full(int(np.prod(self.counts)), NONE, dtype=np.int64)
        self._claim = np.zeros(self._first.size, dtype=np.int64)

    def __call__(self, taps: interp_unit.InterpTaps) -> np.ndarray:
        """The first fragment of every line the slice reads (one entry per line)."""
        cells = taps.cells
        if self.axis is not None:
            cells = cells.copy()
            cells[self.axis] += taps.frac[self.axis] != 0
        n = cells.shape[1]
        if n == 0:
            return np.zeros(0, dtype=np.int64)
        c1, c2 = self.counts[1], self.counts[2]
        ids = []
        for d in self.offsets:
            c = np.minimum(cells + d, self.hi) // self.L
            ids.append((c[0] * c1 + c[1]) * c2 + c[2])
        ids = np.concatenate(ids)
        frags = np.tile(np.arange(n, dtype=np.int64), len(self.offsets))
        np.minimum.at(self._first, ids, frags)
        firsts = np.flatnonzero(self._first[ids] == frags)  # entries at their line's first
        self._claim[ids[firsts]] = np.arange(firsts.size)  # one entry wins each line
        mine = firsts[self._claim[ids[firsts]] == np.arange(firsts.size)]
        self._first[ids] = NONE
        return frags[mine]
