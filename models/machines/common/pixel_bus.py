"""The pixel bus of the slice-order machines as SimPy processes (``transaction`` rung).

# Ref: architectures.md section 1.4 (Cube-4: finished rays leave over one pixel bus) and
#      docs/cycle.md timing rules 4 and 6 (a full pixel FIFO stalls the compositors; the
#      bus drains one pixel per clock, and what is left at the end).

The compositors push finished rays into the pixel FIFO in batches; the bus process sends
them one pixel per clock, in batches of at most one base-plane row or an eighth of the
FIFO, and a batch holds its slots until its last pixel has left.  The FIFO is a
:class:`simpy.Container`'s rule with one producer and one consumer written out
(:meth:`PixelBus._put`, :meth:`PixelBus._get`): each put and get is one plain event,
scheduled exactly when the container's would be: the same cycles and counters without a
container's request objects and queues.  Shared by the VolumePro-family and VIZARD II
event models (the Cube-4 event model uses the cycle rung's ``freezing_fifo``).
"""

from __future__ import annotations

from collections.abc import Generator

import simpy

from hwsim.engine.fifo import DeadlockError

__all__ = ["PixelBus"]


class PixelBus:
    """Pixel FIFO of ``depth`` entries drained one pixel per clock.

    Parameters
    ----------
    env : simpy.Environment
    depth : int
        FIFO entries (0: any push is a deadlock).
    row_pixels : int
        Pixels of one base-plane row (the batch size of a deep FIFO).
    """

    def __init__(self, env: simpy.Environment, depth: int, row_pixels: int) -> None:
        self.env, self.depth = env, int(depth)
        self.capacity, self.level = max(self.depth, 1), 0
        self._waiting: tuple[simpy.Event, int] | None = None  # a put not yet admitted
        self.batch = max(1, min(int(row_pixels), -(-self.depth // 8)))
        self.pushed = self.sent = self.max_occupancy = self.stall_cycles = 0
        self.events = 0
        self.end = 0
        self._work = env.event()
        env.process(self._drain())

    @classmethod
    def totals(cls, depth: int, *, row_pixels: int, **counts: int) -> PixelBus:
        """A finished bus's totals (``pushed``, ``sent``, ``max_occupancy``,
        ``stall_cycles``, ``events``, ``end``) from a run of its rule elsewhere (the
        compiled event loop, :mod:`models.machines.volumepro.pipeline_kernel`), for
        :meth:`counters` and the caller's reads; no process."""
        bus = cls.__new__(cls)
        bus.env, bus.depth = None, int(depth)
        bus.capacity, bus.level, bus._waiting = max(bus.depth, 1), 0, None
        bus.batch = max(1, min(int(row_pixels), -(-bus.depth // 8)))
        for name in ("pushed", "sent", "max_occupancy", "stall_cycles", "events", "end"):
            setattr(bus, name, int(counts.pop(name)))
        if counts:
            raise TypeError(f"unknown totals {sorted(counts)}")
        return bus

    def push(self, count: int) -> Generator:
        """Process step: put ``count`` finished rays, waiting while the FIFO is full."""
        env = self.env
        if count and self.depth <= 0:
            raise DeadlockError(
                f"pixel_bus.fifo: depth {self.depth} can never accept the {count} pixels "
                f"pending at cycle {int(env.now)}; the compositors wait forever"
            )
        waited = env.now
        left = int(count)
        while left:
            chunk = min(left, self.batch)
            yield self._put(chunk)
            self.events += 1
            self.pushed += chunk
            self.max_occupancy = max(self.max_occupancy, self.level)
            left -= chunk
            if not self._work.triggered:
                self._work.succeed()
        self.stall_cycles += int(env.now - waited)

    def _drain(self) -> Generator:
        env = self.env
        while True:
            if self.level == 0:
                self._work = env.event()
                yield self._work
                continue
            chunk = min(self.level, self.batch)
            yield env.timeout(chunk)  # one pixel per clock; the slots free as they leave
            yield self._get(chunk)
            self.events += 2
            self.sent += chunk
            self.end = int(env.now)

    def _put(self, amount: int) -> simpy.Event:
        """``Container.put``: admitted now if it fits (the event scheduled at once), else
        when a get frees room.  One producer: at most one put waits."""
        event = self.env.event()
        if self.capacity - self.level >= amount:
            self.level += amount
            event.succeed()
        else:
            self._waiting = (event, amount)
        return event

    def _get(self, amount: int) -> simpy.Event:
        """``Container.get`` of the bus's own batch (always there: only the bus takes):
        the level drops now; when the event is processed, before the bus resumes, a
        waiting put is admitted if it now fits (the container's ``_trigger_put``)."""
        self.level -= amount
        event = self.env.event()
        event.callbacks.append(self._admit)
        return event.succeed()

    def _admit(self, _event: simpy.Event) -> None:
        if self._waiting is not None and self.capacity - self.level >= self._waiting[1]:
            event, amount = self._waiting
            self._waiting = None
            self.level += amount
            event.succeed()

    def counters(self, pipe_end: int) -> dict[str, int]:
        """``pixel_bus.*`` counters once the frame has run (``pipe_end``: compositors done)."""
        if self.sent != self.pushed:
            raise RuntimeError("transaction model ended with pixels still in the FIFO")
        return {
            "pixel_bus.fifo_depth": self.depth,
            "pixel_bus.pixels": self.pushed,
            "pixel_bus.busy_cycles": self.sent,
            "pixel_bus.max_occupancy": self.max_occupancy,
            "pixel_bus.drain_cycles": max(0, self.end - pipe_end),
        }
