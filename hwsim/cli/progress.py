"""The command line's progress bar: one tqdm bar that stays silent for work under a second,
and a line for first-run work (compiling the kernels, building the RTL) while it happens."""

from __future__ import annotations

import sys
import threading
import time
from collections import defaultdict

from hwsim.core import interrupt, notices

__all__ = ["COMPILING", "first_run_notice", "progress_bar"]

#: What numba compiling a kernel (a cache miss: a cold cache) is shown as.
COMPILING = "compiling kernels, first run only"


class progress_bar:
    """A tqdm bar with an ETA that appears only when the work takes over a second, and
    the :class:`first_run_notice` of the work inside it.

    The callback is ``update(done, total)``, or ``update(done, total, what)`` to name
    the part under way; a later call may give a larger ``total`` (a rung that learns its
    remaining work as it goes).
    """

    def __init__(self, quiet: bool, label: str, unit: str = "step") -> None:
        self.quiet, self.label, self.unit, self.bar = quiet, label, unit, None
        self.notice = first_run_notice(quiet)

    def __enter__(self):
        self.notice.__enter__()
        if self.quiet:
            return None
        return self._update

    def _update(self, done: int, total: int, what: str | None = None) -> None:
        interrupt.check()  # every rung calls this regularly: a stop request ends it here
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total,
                desc=self.label,
                unit=self.unit,
                unit_scale=self.unit != "step",
                delay=1.0,  # keeps short renders silent
                leave=False,
                file=sys.stderr,
            )
        if total != self.bar.total:
            self.bar.total = total
        if what is not None:
            self.bar.set_postfix_str(what, refresh=False)
        self.bar.update(done - self.bar.n)

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()
        self.notice.__exit__(*exc)


class first_run_notice:
    """While first-run work runs, a line naming it with a spinner and the time so far;
    at the end, one line per kind of work saying how long it took.

    Two sources: numba's ``numba:compile`` events, which numba sends only when it
    compiles a kernel (a cache miss, not a load from its on-disk cache), shown as
    :data:`COMPILING`; and :func:`hwsim.core.notices.first_run` (the RTL build).
    Nested work counts once.  Quiet: nothing is shown.
    """

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.lock = threading.Lock()
        self.depth = 0
        self.seconds: dict[str, float] = defaultdict(float)
        self.shown: tuple[str, float, object, threading.Event] | None = None
        self.listener = self.listening = None

    def __enter__(self) -> first_run_notice:
        if self.quiet:
            return self
        from numba.core import event

        self.listener = _numba_compiles(self)
        event.register("numba:compile", self.listener)
        self.listening = notices.listening(self)
        self.listening.__enter__()
        return self

    def start(self, what: str) -> None:
        with self.lock:
            self.depth += 1
            if self.depth == 1:
                self._show(what)

    def end(self, what: str) -> None:
        with self.lock:
            self.depth = max(self.depth - 1, 0)
            if self.depth == 0:
                self._hide()

    def _show(self, what: str) -> None:
        if not sys.stderr.isatty():  # a log or a pipe: one line, no spinner redrawn into it
            print(f"{what} ...", file=sys.stderr)
            self.shown = (what, time.perf_counter(), None, threading.Event())
            return
        from tqdm import tqdm

        bar = tqdm(
            total=None, desc=what, bar_format="{desc} {elapsed}", leave=False, file=sys.stderr
        )
        stop = threading.Event()
        self.shown = (what, time.perf_counter(), bar, stop)
        threading.Thread(target=_spin, args=(bar, what, stop), daemon=True).start()

    def _hide(self) -> None:
        if self.shown is None:
            return
        what, started, bar, stop = self.shown
        self.seconds[what] += time.perf_counter() - started
        stop.set()
        if bar is not None:
            bar.close()  # type: ignore[attr-defined]
        self.shown = None

    def __exit__(self, *exc) -> None:
        if self.quiet:
            return
        from numba.core import event

        event.unregister("numba:compile", self.listener)
        self.listening.__exit__(None, None, None)
        with self.lock:
            self.depth = 0
            self._hide()
        if exc and isinstance(exc[1], KeyboardInterrupt):  # interrupted: its one line only
            return
        for what, seconds in self.seconds.items():
            print(f"{what}: {seconds:.1f} s (cached for the next runs)", file=sys.stderr)


def _spin(bar, what: str, stop: threading.Event) -> None:
    """Turn the spinner of ``bar`` (and refresh its elapsed time) until ``stop``."""
    marks = "|/-\\"
    k = 0
    while not stop.wait(0.25):
        k += 1
        bar.set_description_str(f"{what} {marks[k % 4]}")


def _numba_compiles(notice: first_run_notice):
    """A numba event listener telling ``notice`` of every compile (numba imported here:
    the command line starts without it)."""
    from numba.core import event

    class NumbaCompiles(event.Listener):
        def on_start(self, event) -> None:
            notice.start(COMPILING)

        def on_end(self, event) -> None:
            notice.end(COMPILING)

    return NumbaCompiles()
