"""A pipeline stage: latency and initiation interval as interface, busy/stall/idle counted.

Every cycle of a stage is exactly one of *busy* (it accepted an input), *stalled* (it
held a result its consumer could not take) or *idle* (nothing to do), so
``busy + stalled + idle == total`` per lane -- a test checks it for every unit.  Counts
accumulate in arrays (cheap per block) and reach the counters at :meth:`Stage.publish`.
"""

from __future__ import annotations

import numpy as np

from hwsim.engine.counters import Counters

__all__ = ["Stage"]


class Stage:
    """Accounting of one unit replicated over ``lanes`` pipelines.

    Parameters
    ----------
    unit : str
        Unit name (``interp``); counters go to ``pipeline[i].<unit>.*``.
    latency, ii : int
        Cycles from input to output, and cycles between inputs (the unit model's
        ``LATENCY`` / ``II`` constants).
    lanes : int
    counters : Counters
    """

    def __init__(self, unit: str, latency: int, ii: int, lanes: int, counters: Counters) -> None:
        if latency < 0 or ii < 1:
            raise ValueError(f"{unit}: latency {latency} >= 0 and II {ii} >= 1 required")
        self.unit, self.latency, self.ii, self.lanes = unit, int(latency), int(ii), int(lanes)
        self.counters = counters
        self.path = "pipeline[{}]." + unit
        # busy, stall, idle cycles and inputs per lane; published by :meth:`publish`.
        self._sums = np.zeros((4, self.lanes), dtype=np.int64)

    def account(self, busy: np.ndarray, cycles, stalled=0) -> None:
        """Add blocks of cycles: ``busy[..., i]`` inputs accepted by lane ``i`` in a block of
        ``cycles`` cycles (at most ``cycles / II``), of which every lane spent ``stalled``
        blocked.  One block: ``busy (lanes,)`` and scalars; ``k`` blocks at once:
        ``busy (k, lanes)``, ``cycles`` and ``stalled`` of shape ``(k,)``."""
        busy = np.asarray(busy, dtype=np.int64).reshape(-1, self.lanes)
        cycles = np.asarray(cycles, dtype=np.int64).reshape(-1, 1)
        stalled = np.asarray(stalled, dtype=np.int64).reshape(-1, 1)
        if (busy * self.ii > cycles).any():
            raise ValueError(
                f"{self.unit}: {busy.max()} inputs in a block of {cycles.min()} "
                f"cycles at II {self.ii}"
            )
        idle = cycles - busy * self.ii - stalled
        if (idle < 0).any():
            raise ValueError(f"{self.unit}: busy + stalled exceeds a block of cycles")
        self._sums[0] += (busy * self.ii).sum(axis=0)
        self._sums[1] += np.broadcast_to(stalled, busy.shape).sum(axis=0)
        self._sums[2] += idle.sum(axis=0)
        self._sums[3] += busy.sum(axis=0)

    def publish(self) -> None:
        """Write the accumulated per-lane counts into the counters (once, at the end)."""
        for name, row in zip(
            ("busy_cycles", "stall_cycles", "idle_cycles", "inputs"), self._sums, strict=True
        ):
            self.counters.add_lanes(f"{self.path}.{name}", row)
        self._sums[:] = 0
