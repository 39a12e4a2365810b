"""Logging of hwsim and the libraries it drives: quiet unless asked to be verbose.

One place sets every logger's level, for the ``hwsim`` command (``main`` calls
:func:`configure_logging` with the count of ``--verbose``) and for the worker processes
of the local Dask clusters it starts (:mod:`hwsim.core.cluster` preloads this module in
each worker, whose :func:`dask_setup` repeats the parent's choice, passed on in the Dask
config the nanny hands its worker, key :data:`DASK_KEY`).  Levels by verbosity:

- 0 (default): hwsim's own loggers WARNING and up; the libraries ERROR and up, less the
  known benign shutdown noise (:data:`BENIGN`);
- 1 (``-v``): hwsim and the libraries INFO;
- 2 (``-vv``): DEBUG.

A library importing hwsim configures nothing: only the command line and hwsim's own
worker processes call :func:`configure_logging`.
"""

from __future__ import annotations

import logging
import sys

__all__ = [
    "BENIGN",
    "LIBRARIES",
    "OWN",
    "DASK_KEY",
    "configure_logging",
    "dask_setup",
    "reapply",
    "verbosity",
]

#: hwsim's own top-level packages.
OWN = ("hwsim", "models", "rtl", "benchmarks")

#: The libraries whose loggers speak only from ERROR up unless verbose.  distributed's
#: import sets its own loggers' levels (distributed, tornado, bokeh); whoever imports it
#: first calls :func:`configure_logging` again afterwards (the cluster does).
LIBRARIES = (
    "distributed",
    "dask",
    "numba",
    "asyncio",
    "amaranth",
    "cocotb",
    "tornado",
    "bokeh",
    "matplotlib",
    "PIL",
    "simpy",
    "fsspec",
    "urllib3",
)

#: Known benign noise (logger, message start, exception type names): a worker's heartbeat
#: that meets the scheduler's closed connection while a finished cluster shuts down
#: (distributed.worker logs it with a CommClosedError traceback at ERROR).
BENIGN = (
    (
        "distributed.worker",
        "Failed to communicate with scheduler during heartbeat",
        ("CommClosedError", "StreamClosedError"),
    ),
)

#: The Dask config key that carries the verbosity into the worker processes (not an
#: environment variable: a nanny's pre-spawn environment stays in its parent's).
DASK_KEY = "hwsim.verbosity"

_FORMAT = "%(name)s %(levelname)s: %(message)s"
_state = {"verbosity": 0, "configured": False}


class _Stderr(logging.StreamHandler):
    """A handler writing to whatever ``sys.stderr`` is at the time of each record."""

    def __init__(self) -> None:
        super().__init__()
        self.setFormatter(logging.Formatter(_FORMAT))

    @property
    def stream(self):  # type: ignore[override]
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


class _DropBenign(logging.Filter):
    """Drops the records of :data:`BENIGN` logged on one logger."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.rules = [(start, kinds) for logger, start, kinds in BENIGN if logger == name]

    def filter(self, record: logging.LogRecord) -> bool:
        kind = type(record.exc_info[1]).__name__ if record.exc_info else ""
        message = str(record.msg)
        return not any(message.startswith(s) and kind in kinds for s, kinds in self.rules)


def verbosity() -> int:
    """The verbosity :func:`configure_logging` was last given (0 before any call)."""
    return int(_state["verbosity"])


def configure_logging(verbose: int = 0) -> None:
    """Set the level of hwsim's loggers and the libraries' for ``verbose`` (0, 1, 2+).

    Idempotent: a second call (after a library's import reset its own levels, or with
    another verbosity) sets every level again.  Records go to stderr.
    """
    verbose = max(0, int(verbose))
    own = {0: logging.WARNING, 1: logging.INFO}.get(verbose, logging.DEBUG)
    libraries = {0: logging.ERROR, 1: logging.INFO}.get(verbose, logging.DEBUG)
    root = logging.getLogger()
    if not any(isinstance(h, _Stderr) for h in root.handlers):
        root.addHandler(_Stderr())
    root.setLevel(min(own, libraries))
    for name in OWN:
        logging.getLogger(name).setLevel(own)
    for name in LIBRARIES:
        _set_tree(name, libraries)
    for name in {logger for logger, _, _ in BENIGN}:
        log = logging.getLogger(name)
        for old in [f for f in log.filters if isinstance(f, _DropBenign)]:
            log.removeFilter(old)
        if verbose == 0:
            log.addFilter(_DropBenign(name))
    _state.update(verbosity=verbose, configured=True)


def _set_tree(name: str, level: int) -> None:
    """``name``'s level, and its existing children's where set (distributed sets some)."""
    logging.getLogger(name).setLevel(level)
    for other, logger in list(logging.Logger.manager.loggerDict.items()):
        if other.startswith(name + ".") and isinstance(logger, logging.Logger):
            if logger.level != logging.NOTSET:
                logger.setLevel(level)


def reapply() -> None:
    """Import distributed (its first import sets its own loggers' levels) and set the
    levels again, if the command line configured logging in this process; a library
    user's settings stay.  Called where hwsim starts or reaches a Dask cluster."""
    import distributed  # noqa: F401

    if _state["configured"]:
        configure_logging(verbosity())


def dask_setup(worker: object) -> None:
    """Dask preload hook, run in each worker process of hwsim's local clusters: the
    parent's verbosity (Dask config :data:`DASK_KEY`, default 0) applied there."""
    import dask

    configure_logging(int(dask.config.get(DASK_KEY, default=0)))
