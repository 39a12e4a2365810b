"""A ready/valid FIFO drained at a fixed rate, advanced in blocks (e.g. the pixel bus).

Producers push ``n`` entries at the end of a block of ``cycles`` cycles; the consumer
pops ``rate`` entries per cycle.  When a push would overflow ``depth`` the producer
stalls (``ready`` low) until the consumer has made room, each stall cycle popping
``rate`` entries, so every cycle stays exact.  A FIFO that can never accept what is
pending (depth 0) is a deadlock, reported with the cycle and the waiting count rather
than hanging.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DrainFifo", "DeadlockError", "FreezingFifoRun", "freezing_fifo"]


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


@dataclass
class FreezingFifoRun:
    """What :func:`freezing_fifo` found: pop clock of every entry (in push order),
    the producer's frozen clocks (at their stall-free times) and the FIFO's counters
    (``pushed``, ``popped``, ``busy_cycles``, ``max_occupancy``, ``depth``, ``name``:
    the attributes :class:`DrainFifo` reports)."""

    name: str
    depth: int
    pops: np.ndarray
    frozen_at: np.ndarray
    max_occupancy: int

    @property
    def pushed(self) -> int:
        return int(self.pops.size)

    @property
    def popped(self) -> int:
        return int(self.pops.size)

    @property
    def busy_cycles(self) -> int:
        return int(self.pops.size)  # one entry per clock

    @property
    def stall_cycles(self) -> int:
        return int(self.frozen_at.size)

    def shift_at(self, clock: int) -> int:
        """Frozen clocks before the producer's stall-free clock ``clock`` (how much later
        it happened)."""
        return int(np.searchsorted(self.frozen_at, clock, side="left"))


def freezing_fifo(name: str, push_clocks: np.ndarray, depth: int) -> FreezingFifoRun:
    """A FIFO popped one entry per clock whose producer freezes while it cannot push.

    ``push_clocks`` (ascending) are the clocks at which entries would be pushed if the
    producer never froze; entries pushed in one clock go in in the given order.  In a
    clock the FIFO takes as many of that clock's entries as it has room for (``depth``
    minus the entries pushed and not yet popped before the clock); if any is left the
    producer freezes for the clock (every later push happens one clock later) and pushes
    the rest the next clock.  An entry pushed in clock ``c`` can be popped from ``c + 1``;
    one pop per clock, in push order.  This is the RTL top's pixel FIFO (rtl/top.py).
    """
    push = np.asarray(push_clocks, dtype=np.int64)
    n = push.size
    if n and depth <= 0:
        raise DeadlockError(
            f"{name}: depth {depth} can never accept the {n} entries pending at cycle "
            f"{int(push[0])}; the producer waits forever"
        )
    if n == 0:
        return FreezingFifoRun(name, depth, push.copy(), push.copy(), 0)
    idx = np.arange(n, dtype=np.int64)
    # Never frozen: pop_i = max over k <= i of (push_k + 1 + i - k).
    pops = idx + np.maximum.accumulate(push + 1 - idx)
    # Entries in the FIFO right after each push clock's entries went in.
    occupancy = idx + 1 - np.searchsorted(pops, push, side="left")
    if int(occupancy.max()) <= depth:
        return FreezingFifoRun(name, depth, pops, np.zeros(0, np.int64), int(occupancy.max()))
    return _freezing_fifo_loop(name, push, depth)


def _freezing_fifo_loop(name: str, push: np.ndarray, depth: int) -> FreezingFifoRun:
    """:func:`freezing_fifo` clock by clock (only when the FIFO does fill up)."""
    n = push.size
    pops = np.empty(n, dtype=np.int64)
    frozen: list[int] = []
    shift = 0  # frozen clocks so far
    last_pop = -1
    head = 0  # entries popped before the current clock
    i = 0
    peak = 0
    while i < n:
        nominal = int(push[i])
        clock = nominal + shift
        end = i
        while end < n and push[end] == nominal:
            end += 1
        while i < end:
            while head < i and pops[head] < clock:
                head += 1
            room = depth - (i - head)
            take = min(room, end - i)
            for k in range(i, i + take):
                last_pop = max(clock + 1, last_pop + 1)
                pops[k] = last_pop
            i += take
            peak = max(peak, i - head)
            if i < end:
                frozen.append(nominal)
                shift += 1
                clock += 1
    return FreezingFifoRun(name, depth, pops, np.asarray(frozen, dtype=np.int64), peak)
