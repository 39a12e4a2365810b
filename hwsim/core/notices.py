"""First-run work announced to whoever shows it (the command line's progress bar).

Some work happens once per machine and is then cached: numba compiling the frame kernels
(announced by numba itself, ``numba:compile`` events, see :mod:`hwsim.cli.progress`) and
the RTL rung's Verilog export and simulator build (:mod:`rtl.rung`).  A library function
doing such work wraps it in :func:`first_run`; a listener registered with
:func:`listening` is told when it starts and ends.  Without a listener it costs nothing.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Protocol

__all__ = ["FirstRunListener", "first_run", "listening"]


class FirstRunListener(Protocol):
    """What is told of first-run work: ``start(what)`` and ``end(what)``, paired."""

    def start(self, what: str) -> None: ...

    def end(self, what: str) -> None: ...


_listeners: list[FirstRunListener] = []


@contextlib.contextmanager
def first_run(what: str) -> Iterator[None]:
    """Announce the work in the ``with`` block as first-run work named ``what`` (a short
    phrase such as ``"building RTL (Verilator), first run only"``)."""
    for listener in list(_listeners):
        listener.start(what)
    try:
        yield
    finally:
        for listener in list(_listeners):
            listener.end(what)


@contextlib.contextmanager
def listening(listener: FirstRunListener) -> Iterator[None]:
    """Tell ``listener`` of every :func:`first_run` inside the ``with`` block."""
    _listeners.append(listener)
    try:
        yield
    finally:
        _listeners.remove(listener)
