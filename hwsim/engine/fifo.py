"""A ready/valid FIFO drained at a fixed rate, advanced in blocks (e.g. the pixel bus).

Producers push ``n`` entries at the end of a block of ``cycles`` cycles; the consumer
pops ``rate`` entries per cycle.  When a push would overflow ``depth`` the producer
stalls (``ready`` low) until the consumer has made room, each stall cycle popping
``rate`` entries, so every cycle stays exact.  A FIFO that can never accept what is
pending (depth 0) is a deadlock, reported with the cycle and the waiting count rather
than hanging.
"""

from __future__ import annotations

__all__ = ["DrainFifo", "DeadlockError"]


class DeadlockError(RuntimeError):
    """The modelled hardware can make no further progress."""


class DrainFifo:
    """Occupancy-exact FIFO with a constant drain rate.

    Parameters
    ----------
    name : str
        Component path used in reports.
    depth : int
        Entries the FIFO holds.
    rate : int
        Entries the consumer pops per cycle (>= 1).
    """

    def __init__(self, name: str, depth: int, rate: int = 1) -> None:
        if rate < 1:
            raise ValueError(f"{name}: drain rate {rate} must be >= 1")
        self.name, self.depth, self.rate = name, int(depth), int(rate)
        self.occupancy = 0
        self.max_occupancy = 0
        self.pushed = 0
        self.popped = 0
        self.busy_cycles = 0  # cycles the consumer popped at least one entry

    def _drain(self, cycles: int) -> None:
        out = min(self.occupancy, cycles * self.rate)
        self.busy_cycles += -(-out // self.rate)
        self.occupancy -= out
        self.popped += out

    def advance(self, cycles: int, arrivals: int, now: int) -> int:
        """Drain for ``cycles`` cycles, then push ``arrivals`` entries.

        Returns the stall cycles the producer spent waiting for room (0 when it fits).
        ``now`` is the cycle at the start of the block (for the deadlock report).
        """
        self._drain(cycles)
        if arrivals and self.depth <= 0:
            raise DeadlockError(
                f"{self.name}: depth {self.depth} can never accept the {arrivals} entries "
                f"pending at cycle {now + cycles}; the producer waits forever"
            )
        stall = 0
        space = self.depth - self.occupancy
        remaining = arrivals
        while remaining > space:
            # Entries that fit go in now; each stall cycle then frees ``rate`` slots.
            self.occupancy += space
            remaining -= space
            self.max_occupancy = max(self.max_occupancy, self.occupancy)
            need = (
                -(-remaining // self.rate)
                if remaining <= self.depth
                else -(-self.depth // self.rate)
            )
            self._drain(need)
            stall += need
            space = self.depth - self.occupancy
        self.occupancy += remaining
        self.pushed += arrivals
        self.max_occupancy = max(self.max_occupancy, self.occupancy)
        return stall

    def flush(self) -> int:
        """Cycles until the FIFO is empty (drained at the end of a frame)."""
        cycles = -(-self.occupancy // self.rate)
        self._drain(cycles)
        return cycles
