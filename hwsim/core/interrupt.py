"""Ctrl-C: a process-wide stop request, so that an interrupt ends a command in seconds.

Python delivers SIGINT to the main thread only, between bytecodes: a frame's worker
threads (:func:`hwsim.core.threads.pool`, the compiled kernels run with the GIL released)
would go on to the end of the frame, and the interpreter waits for them at exit.  While
:func:`handling_sigint` is active (the command line wraps every command in it), the
first SIGINT sets a flag and raises ``KeyboardInterrupt`` in the main thread; the loops
that run on other threads call :func:`check` between steps (a tile of rays, a step of
samples) and stop there.  A second SIGINT ends the process at once (status 130).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress

__all__ = [
    "EXIT_STATUS",
    "Interrupted",
    "check",
    "dask_setup",
    "exit_now",
    "handling_sigint",
    "requested",
    "say",
]

#: The exit status of an interrupted command (128 + SIGINT, as a shell reports it).
EXIT_STATUS = 130
#: The one line an interrupted command prints.
MESSAGE = "hwsim: interrupted"

_stop = threading.Event()
_said = threading.Event()


class Interrupted(KeyboardInterrupt):
    """Raised by :func:`check` in a thread that finds a stop request."""


def requested() -> bool:
    """Whether a stop has been requested (SIGINT) since the command started."""
    return _stop.is_set()


def check() -> None:
    """Raise :class:`Interrupted` if a stop has been requested: called between steps."""
    if _stop.is_set():
        raise Interrupted


def say() -> None:
    """Print :data:`MESSAGE` on stderr, once per command."""
    if not _said.is_set():
        _said.set()
        os.write(2, f"{MESSAGE}\n".encode())


def _on_sigint(signum, frame) -> None:
    if _stop.is_set():  # the second Ctrl-C: no clean-up, now
        exit_now(signum, frame)
    _stop.set()
    raise KeyboardInterrupt


def exit_now(signum=None, frame=None) -> None:
    """A SIGINT handler that prints :data:`MESSAGE` and ends the process at once (status
    130): a second Ctrl-C, and every Ctrl-C while the command line is still starting
    (``hwsim.cli``'s entry point installs it before importing the commands), when there
    is nothing to clean up and a ``KeyboardInterrupt`` could surface as a traceback of an
    import, or be printed and swallowed inside a callback ("Exception ignored in ...")."""
    say()
    _end_children()
    os._exit(EXIT_STATUS)


def _end_children() -> None:
    """Before leaving at once: kill this process's multiprocessing children (a local
    cluster's workers) and run multiprocessing's finalizers that unlink the
    semaphores it made, so its resource tracker finds none leaked (it warned of a
    dozen after a second Ctrl-C in a split frame)."""
    import gc
    import sys

    if "multiprocessing" not in sys.modules:  # none started: nothing to end
        return
    from multiprocessing import active_children, util

    gc.disable()  # no object's __del__ now: a Dask client's would find its loop closed
    for child in active_children():
        with suppress(Exception):
            child.kill()
    with suppress(Exception):
        util._run_finalizers(0)  # a semaphore's finalizer (priority 0) unlinks it


def dask_setup(worker) -> None:
    """A local cluster's worker processes ignore SIGINT (a Dask preload): a Ctrl-C at the
    terminal reaches the whole process group, and the command that started the cluster
    closes it; a worker would otherwise print its own traceback."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def handling_sigint() -> Iterator[None]:
    """Run a command with the stop request cleared and SIGINT handled as above (outside
    the main thread, where no signal handler can be set, only the flag is cleared)."""
    _stop.clear()
    _said.clear()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
