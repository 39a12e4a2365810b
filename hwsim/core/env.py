"""Every ``HWSIM_*`` environment variable, declared once and checked like a flag.

Each variable has a parser that turns its text into a value or raises
:class:`~hwsim.core.errors.InputError` naming the variable and its allowed range.  The
command line calls :func:`validate` before any work, so ``HWSIM_THREADS=abc`` is one
line and exit status 2, not an internal error in the middle of a frame or a traceback
in a Dask worker; the library reads values through :func:`value`.  An unset or empty
variable means its default.  docs/cli.md lists them (tests/test_env.py checks that the
table names each one, and that the code reads no other).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError

__all__ = ["VARIABLES", "Carried", "Variable", "carrying", "settings", "validate", "value"]

#: Most threads per frame (``HWSIM_THREADS``, ``--threads``).
MAX_THREADS = 256
#: Most samples one frame may be allowed to plan (``HWSIM_MAX_SAMPLES``).
MAX_SAMPLES_LIMIT = 10**15


@dataclass(frozen=True)
class Variable:
    """One environment variable: its name, what it sets, its allowed values and default."""

    name: str
    meaning: str
    allowed: str
    default: str
    parse: Callable[[str, str], Any]
    #: Sent with work to Dask workers (:func:`settings`); a folder of this machine is not.
    sent: bool = True


def _count(lo: int, hi: int) -> Callable[[str, str], int]:
    """A parser of whole numbers ``lo .. hi`` (``1e10`` style allowed when whole)."""

    def parse(name: str, text: str) -> int:
        try:
            number = float(text.strip())
        except ValueError:
            number = math.nan
        if not (math.isfinite(number) and number == int(number) and lo <= number <= hi):
            raise InputError(f"{text!r} is not a whole number in range", key=name,
                             allowed=f"{lo} .. {hi}")  # fmt: skip
        return int(number)

    return parse


def _size(name: str, text: str) -> int:
    from hwsim.core.budget import parse_size

    return parse_size(text, key=name)


_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def _flag(name: str, text: str) -> bool:
    word = text.strip().lower()
    if word not in _TRUE + _FALSE:
        raise InputError(f"{text!r} is not a switch", key=name, allowed="0 or 1")
    return word in _TRUE


def _folder(name: str, text: str) -> Path:
    path = Path(text).expanduser()
    try:
        wrong = "\0" in text or (path.exists() and not path.is_dir())
    except OSError as exc:  # a name too long, a loop of links
        raise InputError(f"{exc.strerror or exc}", key=name, allowed="a folder path") from None
    if wrong:
        raise InputError(f"{text!r} is not a folder", key=name, allowed="a folder path")
    return path


VARIABLES: dict[str, Variable] = {
    v.name: v
    for v in (
        Variable("HWSIM_THREADS", "threads per frame (as --threads)", f"1 .. {MAX_THREADS}",
                 "every usable core; 1 in sweep workers", _count(1, MAX_THREADS)),
        Variable("HWSIM_MAX_MEMORY", "memory budget per process (as --max-memory)",
                 "bytes, or a number with K, M, G or T; 1M .. 1024T",
                 "half the available memory", _size),
        Variable("HWSIM_MAX_SAMPLES", "most samples one frame may plan",
                 f"1 .. {MAX_SAMPLES_LIMIT:.0e} (whole; 1e10 style allowed)", "1e10",
                 _count(1, MAX_SAMPLES_LIMIT)),
        Variable("HWSIM_DEBUG", "show the traceback of an internal error",
                 "0 or 1 (also true/false, yes/no, on/off)", "0", _flag),
        Variable("HWSIM_RTL_BUILD", "folder of the rtl rung's Verilator and Icarus builds",
                 "a folder path (made if missing)", "build/rtl in the source tree", _folder,
                 sent=False),
        Variable("HWSIM_SHARED_DATA", "benchmarks only: folder of the shared volumes",
                 "a folder path", "../shared/data next to the source tree", _folder,
                 sent=False),
    )
}  # fmt: skip


def value(name: str) -> Any:
    """The parsed value of ``name`` (one of :data:`VARIABLES`), or None when unset/empty.

    Raises
    ------
    InputError
        Naming the variable and its allowed values when the text does not parse.
    """
    carried = _carried.get()
    if carried is not None and name in carried:
        text = carried[name]
    else:
        text = os.environ.get(name, "")
    if not text.strip():
        return None
    return VARIABLES[name].parse(name, text)


def validate() -> None:
    """Parse every variable of :data:`VARIABLES` (the command line, before any work)."""
    for name in VARIABLES:
        value(name)


# ----------------------------------------------------------------- settings sent with work

#: The client's settings while a worker runs its work (:func:`carrying`); None: this
#: process's own environment.
_carried: ContextVar[dict[str, str] | None] = ContextVar("hwsim_env_carried", default=None)


def settings(**defaults: str) -> dict[str, str]:
    """The texts of every variable sent with work (``sent``), checked here first: what a
    Dask worker, local or remote, is to use instead of its own environment.  An unset
    variable is sent as ``defaults[name]`` when given (a sweep's workers: one thread),
    else empty (the default), so a worker's own value never applies."""
    validate()
    texts = {n: os.environ.get(n, "") for n, v in VARIABLES.items() if v.sent}
    for name, text in defaults.items():
        if not texts[name].strip():
            texts[name] = text
    return texts


@contextmanager
def carrying(texts: dict[str, str]) -> Iterator[None]:
    """Inside the block, :func:`value` reads ``texts`` (from :func:`settings`) for the
    variables they hold, not this process's environment (a worker running the client's
    work; the threads of the block's own thread only, so concurrent tasks of other
    clients keep theirs)."""
    token = _carried.set(dict(texts))
    try:
        yield
    finally:
        _carried.reset(token)


class Carried:
    """``fn`` run under the client's :func:`settings`: what the command line submits to
    Dask (``client.submit(Carried(fn, settings()), ...)``), so a worker started with
    other ``HWSIM_*`` values (a remote ``--scheduler`` cluster) renders as the client
    asked."""

    def __init__(self, fn: Callable[..., Any], texts: dict[str, str]) -> None:
        self.fn, self.texts = fn, dict(texts)
        self.__name__ = getattr(fn, "__name__", "carried")  # Dask names tasks by it

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        with carrying(self.texts):
            return self.fn(*args, **kwargs)
