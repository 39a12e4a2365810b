"""The clock of a modelled machine: the cycle counter every component is timed against."""

from __future__ import annotations

__all__ = ["Clock"]


class Clock:
    """Counts cycles of one clock domain.

    Parameters
    ----------
    hz : float
        Frequency, for converting cycles to seconds.
    """

    def __init__(self, hz: float) -> None:
        if not hz > 0:
            raise ValueError(f"clock frequency {hz} must be > 0")
        self.hz = float(hz)
        self.cycle = 0

    def advance(self, cycles: int) -> int:
        """Let ``cycles`` (>= 0) clocks pass; returns the cycle reached."""
        if cycles < 0:
            raise ValueError(f"a clock cannot go back {cycles} cycles")
        self.cycle += int(cycles)
        return self.cycle

    @property
    def seconds(self) -> float:
        """Time elapsed since cycle 0."""
        return self.cycle / self.hz
