"""Ready/valid channels, with Amaranth ``lib.stream`` rules (conventions.md item 3).

A payload moves on a cycle exactly when ``valid & ready``; ``valid`` must not depend on
``ready``, and once raised it stays until the transfer.  A :class:`Channel` checks those
rules over a block of cycles and counts transfers, stall cycles (valid, not ready) and
idle cycles (not valid), per lane.
"""

from __future__ import annotations

import numpy as np

from hwsim.engine.counters import Counters

__all__ = ["Channel"]


class Channel:
    """One ready/valid link per lane, observed in blocks of cycles.

    Parameters
    ----------
    path : str
        Component path with a ``{}`` for the lane (``pipeline[{}].interp.i``).
    lanes : int
        Parallel lanes.
    counters : Counters
        Where ``.transfers``, ``.stall_cycles`` and ``.idle_cycles`` go at :meth:`publish`.
    """

    def __init__(self, path: str, lanes: int, counters: Counters) -> None:
        self.path, self.lanes, self.counters = path, lanes, counters
        self._held = np.zeros(lanes, dtype=bool)  # valid high without ready at block end
        self._sums = np.zeros((3, lanes), dtype=np.int64)

    def observe(self, valid: np.ndarray, ready: np.ndarray) -> np.ndarray:
        """Account one block: ``valid``/``ready`` ``(lanes, L)`` bools; returns the
        transfer mask.  Raises ``ValueError`` when valid drops before its transfer."""
        valid = np.asarray(valid, dtype=bool)
        ready = np.broadcast_to(np.asarray(ready, dtype=bool), valid.shape)
        prev_valid = np.concatenate([self._held[:, None], valid[:, :-1]], axis=1)
        prev_ready = np.concatenate([np.zeros((self.lanes, 1), bool), ready[:, :-1]], axis=1)
        dropped = prev_valid & ~prev_ready & ~valid
        if dropped.any():
            lane, cycle = np.argwhere(dropped)[0]
            raise ValueError(
                f"{self.path.format(lane)}: valid fell without a transfer at block cycle {cycle}"
            )
        fire = valid & ready
        self._held = valid[:, -1] & ~ready[:, -1]
        transfers = fire.sum(axis=1)
        self.account(transfers, valid.sum(axis=1) - transfers, valid.shape[1] - valid.sum(axis=1))
        return fire

    def account(self, transfers: np.ndarray, stalls: np.ndarray, idles: np.ndarray) -> None:
        """Add one block's per-lane transfers, stalled and idle cycles counted elsewhere
        (a link that is always ready: transfers are its valid cycles, no stalls)."""
        self._sums[0] += transfers
        self._sums[1] += stalls
        self._sums[2] += idles

    def publish(self) -> None:
        """Write the accumulated per-lane counts into the counters."""
        for name, row in zip(("transfers", "stall_cycles", "idle_cycles"), self._sums, strict=True):
            self.counters.add_lanes(f"{self.path}.{name}", row)
        self._sums[:] = 0
