"""A lean event loop with SimPy's scheduling rule, for the VolumePro-family event model.

# Ref: simpy.core.Environment (step, schedule) and simpy.events (Event, Timeout,
#      Process._resume), SimPy 4: the rule written again for the few parts the model uses.

The event model (:mod:`models.machines.volumepro.transaction`, its pixel bus
:class:`~models.machines.common.pixel_bus.PixelBus` and memory process
:func:`~models.machines.volumepro.chunk_reads.memory_process`) uses a small part of
SimPy: plain events (``env.event()``, ``succeed``, ``triggered``, callbacks), timeouts
and generator processes.  :class:`EventLoop` runs those with SimPy's order, so the
same cycles and counters, at a fraction of the interpreter work a step:

* the queue holds ``(time, priority, sequence, event)``, a process's start URGENT (0),
  every other event NORMAL (1), the sequence counting every scheduling in order: the
  order SimPy processes events in (a same-cycle tie goes to the event scheduled first);
* processing an event calls its callbacks in the order they were added (the pixel bus's
  admission before the process waiting on the get);
* a process resumed by an event sends the event's value into its generator and goes on
  at once while it yields events already processed; it waits on one triggered or
  pending event by adding itself to its callbacks.

What is left out changes no order: a finished process's own event (no one waits on one
here: it would only take a sequence number, which shifts no other event's relative
order), failed events, interrupts, conditions and ``run(until=...)``.  An exception a
process raises leaves :meth:`EventLoop.run` at once (SimPy processes the same cycle's
earlier events first and raises a copy: the same exception type and message, as no
process here raises otherwise).  ``tests/models/test_event_loop.py`` holds the model's
results on random frames to SimPy's (``SlabTransaction(..., events="simpy")``).
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from heapq import heappop, heappush
from itertools import count
from typing import Any

__all__ = ["EventLoop", "LeanEvent"]

_PENDING = object()
_URGENT, _NORMAL = 0, 1


class LeanEvent:
    """``simpy.Event``'s state: ``callbacks`` (None once processed) and a value."""

    __slots__ = ("callbacks", "_value", "_loop")

    def __init__(self, loop: EventLoop, value: Any = _PENDING) -> None:
        self._loop = loop
        self.callbacks: list[Callable[[LeanEvent], None]] | None = []
        self._value = value

    @property
    def triggered(self) -> bool:
        return self._value is not _PENDING

    @property
    def processed(self) -> bool:
        return self.callbacks is None

    @property
    def value(self) -> Any:
        return self._value

    def succeed(self, value: Any = None) -> LeanEvent:
        """Trigger the event now (scheduled NORMAL behind the events already queued)."""
        if self._value is not _PENDING:
            raise RuntimeError(f"{self} has already been triggered")
        self._value = value
        loop = self._loop
        heappush(loop._queue, (loop.now, _NORMAL, next(loop._seq), self))
        return self


class _Process:
    """A generator process: resumed by each event it waits on (``Process._resume``)."""

    __slots__ = ("_generator",)

    def __init__(self, generator: Generator) -> None:
        self._generator = generator

    def resume(self, event: LeanEvent) -> None:
        send = self._generator.send
        while True:
            try:
                event = send(event._value)
            except StopIteration:
                return
            callbacks = event.callbacks
            if callbacks is not None:
                callbacks.append(self.resume)
                return


class EventLoop:
    """The part of ``simpy.Environment`` the event model uses, SimPy's order kept."""

    def __init__(self) -> None:
        self.now = 0
        self._queue: list[tuple[int, int, int, LeanEvent]] = []
        self._seq = count()

    def event(self) -> LeanEvent:
        return LeanEvent(self)

    def timeout(self, delay: int, value: Any = None) -> LeanEvent:
        if delay < 0:
            raise ValueError(f"Negative delay {delay}")
        event = LeanEvent(self, value)
        heappush(self._queue, (self.now + delay, _NORMAL, next(self._seq), event))
        return event

    def process(self, generator: Generator) -> None:
        """Start ``generator`` as a process (its first step an URGENT event now)."""
        start = LeanEvent(self, None)
        start.callbacks.append(_Process(generator).resume)
        heappush(self._queue, (self.now, _URGENT, next(self._seq), start))

    def run(self) -> None:
        """Process events until none is left."""
        queue = self._queue
        while queue:
            self.now, _, _, event = heappop(queue)
            callbacks, event.callbacks = event.callbacks, None
            for callback in callbacks:
                callback(event)
