"""Delay lines: fixed-depth FIFOs with no back-pressure (a beam or slice delay of Cube-4).

A delay line of depth ``D`` outputs, at cycle ``t``, exactly what entered it at cycle
``t - D`` (its reset contents, zeros, before that).  :meth:`DelayLine.push` advances a
block of ``L`` cycles on every lane at once and stays cycle-exact across blocks, so a
line one entry too shallow really delivers data one cycle early -- the fault a test can
inject.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DelayLine"]


class DelayLine:
    """``lanes`` parallel delay lines of ``depth`` entries each.

    Parameters
    ----------
    depth : int
        Entries per lane (cycles of delay), >= 0.
    lanes : int
        Parallel lanes (one per pipeline).
    dtype : numpy dtype
        Entry type.
    """

    def __init__(self, depth: int, lanes: int, dtype=np.int64) -> None:
        if depth < 0 or lanes < 1:
            raise ValueError(f"delay line: depth {depth} must be >= 0 and lanes {lanes} >= 1")
        self.depth, self.lanes = int(depth), int(lanes)
        self._state = np.zeros((lanes, depth), dtype=dtype)
        self.pushed = 0  # entries written per lane

    def push(self, block: np.ndarray) -> np.ndarray:
        """Write ``block`` ``(lanes, L)`` (cycles along axis 1); return the ``(lanes, L)``
        entries leaving the line over the same ``L`` cycles."""
        if block.shape[0] != self.lanes:
            raise ValueError(f"delay line has {self.lanes} lanes, block has {block.shape[0]}")
        length = block.shape[1]
        self.pushed += length
        if self.depth == 0:
            return block
        joined = np.concatenate([self._state, block.astype(self._state.dtype)], axis=1)
        self._state = joined[:, length:]
        return joined[:, :length]

    @staticmethod
    def read_at(block: np.ndarray, flat_cycles: np.ndarray, cycles: np.ndarray, depth: int):
        """What a freshly reset line of ``depth`` fed ``block`` outputs at given cycles.

        ``flat_cycles`` indexes ``block.ravel()`` (lane * L + cycle) and ``cycles`` is the
        cycle part; entries read before anything reached the output are the reset zeros.
        Same result as :meth:`push` followed by indexing, without building the output.
        """
        if depth == 0:
            return block.ravel()[flat_cycles]
        out = block.ravel()[np.maximum(flat_cycles - depth, 0)]
        return np.where(cycles >= depth, out, 0)

    @property
    def entries(self) -> int:
        """Storage of the line in entries (all lanes)."""
        return self.depth * self.lanes
