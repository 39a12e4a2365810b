"""A pipeline stage: latency and initiation interval as interface, busy/stall/idle counted.

Every cycle of a stage is exactly one of *busy* (it accepted an input), *stalled* (it
held a result its consumer could not take) or *idle* (nothing to do), so
``busy + stalled + idle == total`` per lane -- a test checks it for every unit.
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

    def account(self, busy: np.ndarray, cycles: int, stalled: int = 0) -> None:
        """Add one block of ``cycles`` cycles: ``busy[i]`` inputs accepted by lane ``i``
        (at most ``cycles / II``), ``stalled`` cycles every lane spent blocked."""
        busy = np.asarray(busy, dtype=np.int64)
        if (busy * self.ii > cycles).any():
            raise ValueError(f"{self.unit}: {busy.max()} inputs in {cycles} cycles at II {self.ii}")
        idle = cycles - busy * self.ii - stalled
        if (idle < 0).any():
            raise ValueError(f"{self.unit}: busy + stalled exceeds the block of {cycles} cycles")
        self.counters.add_lanes(self.path + ".busy_cycles", busy * self.ii)
        self.counters.add_lanes(self.path + ".stall_cycles", np.full(self.lanes, stalled))
        self.counters.add_lanes(self.path + ".idle_cycles", idle)
        self.counters.add_lanes(self.path + ".inputs", busy)
