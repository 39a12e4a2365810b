"""The memory budget: what one run may allocate, checked before it allocates.

Every reader computes the bytes a file's header declares (and, for compressed data,
the inflated size) and every render estimates its largest arrays *before* allocating
them; both ask :func:`require_fits`.  A header that lies, or a plan that would not fit,
is then a one-line input error (exit status 2) instead of a ``MemoryError``, a swapping
machine or a kill by the kernel.

The budget is, in order of precedence: :func:`set_memory_budget` (the CLI's
``--max-memory``), the environment variable ``HWSIM_MAX_MEMORY``, or
:data:`DEFAULT_FRACTION` of the memory the operating system reports as available.
Sizes are written as bytes or with a binary suffix: ``512M``, ``2G``, ``1.5GiB``.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator

from hwsim.core.env import value
from hwsim.core.errors import InputError

__all__ = [
    "DEFAULT_FRACTION",
    "available_memory_bytes",
    "format_bytes",
    "memory_budget",
    "parse_size",
    "require_fits",
    "set_memory_budget",
    "memory_budget_of",
    "sample_budget",
    "SAMPLE_ENV_VAR",
    "DEFAULT_MAX_SAMPLES",
]

#: Share of the available memory one run may plan to use when no budget is given: the
#: rest is head room for the interpreter, temporaries the estimates do not count, and
#: the other processes of the machine (a second sweep worker, the user's desktop).
DEFAULT_FRACTION = 0.5
#: What is assumed available when the operating system does not say (4 GiB).
FALLBACK_AVAILABLE = 4 << 30
ENV_VAR = "HWSIM_MAX_MEMORY"
#: Most samples one frame may plan before it is refused (about an hour of the golden
#: renderer, 5-10 minutes of the functional rung): a scene that asks for more is almost
#: always a typo (a sample spacing of 1e-4, a 1e6 supersampling).
DEFAULT_MAX_SAMPLES = 10**10
SAMPLE_ENV_VAR = "HWSIM_MAX_SAMPLES"

#: The largest size accepted (1024 TiB): above it, a typo.
MAX_SIZE = 1 << 50
_SUFFIX = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}
_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(?:i?b)?\s*$", re.IGNORECASE)
_override: int | None = None


def parse_size(text: str, *, key: str = "--max-memory") -> int:
    """Bytes from ``"2G"``, ``"512MiB"``, ``"1.5GB"`` or a plain integer (binary units).

    Raises
    ------
    InputError
        Naming ``key`` when ``text`` is not a size or is below 1 MiB.
    """
    match = _SIZE.match(str(text))
    if not match:
        raise InputError(
            f"{text!r} is not a size", key=key, allowed="bytes, or a number with K, M, G or T"
        )
    value = float(match.group(1)) * _SUFFIX[match.group(2).lower()]
    if not 1 << 20 <= value <= MAX_SIZE:  # also inf, from 400 digits
        raise InputError(f"{text!r} is out of range", key=key, allowed="1M .. 1024T")
    return int(value)


def available_memory_bytes() -> int:
    """Memory the operating system reports as available (``MemAvailable`` on Linux)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return FALLBACK_AVAILABLE


def set_memory_budget(nbytes: int | None) -> None:
    """Fix the budget for this process (``None``: back to the environment or default)."""
    global _override
    _override = None if nbytes is None else int(nbytes)


@contextlib.contextmanager
def memory_budget_of(nbytes: int) -> Iterator[None]:
    """Run a block under a budget of ``nbytes``, also exported as ``HWSIM_MAX_MEMORY`` so
    the processes it starts (sweep workers) inherit it; both are restored afterwards, so
    one in-process CLI call does not bound the next."""
    global _override
    saved, saved_env = _override, os.environ.get(ENV_VAR)
    _override = int(nbytes)
    os.environ[ENV_VAR] = str(int(nbytes))
    try:
        yield
    finally:
        _override = saved
        if saved_env is None:
            os.environ.pop(ENV_VAR, None)
        else:
            os.environ[ENV_VAR] = saved_env


def memory_budget() -> int:
    """Bytes one run may plan to allocate (see the module docstring for the order)."""
    if _override is not None:
        return _override
    env = value(ENV_VAR)
    if env is not None:
        return env
    return int(available_memory_bytes() * DEFAULT_FRACTION)


def format_bytes(nbytes: float) -> str:
    """``1536`` -> ``"1.5 KiB"``: sizes in messages, binary units."""
    value = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(value) < 1024 or unit == "TiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1024
    raise AssertionError("unreachable")


def require_fits(nbytes: float, *, what: str, source: str | None = None, key: str | None = None):
    """Refuse, before allocating, ``nbytes`` that exceed :func:`memory_budget`.

    Parameters
    ----------
    nbytes : float
        The bytes the caller is about to allocate (declared by a header, or estimated).
    what : str
        What they are for, e.g. ``"voxel data 1024x1024x1024 uint8"``.
    source, key : str, optional
        The file (or flag) and key the size came from, for the one-line message.

    Raises
    ------
    InputError
        With both sizes and how to raise the budget.
    """
    budget = memory_budget()
    if nbytes > budget:
        raise InputError(
            f"{what} needs {format_bytes(nbytes)}, over the memory budget of "
            f"{format_bytes(budget)} (set --max-memory or {ENV_VAR} to raise it)",
            source=source,
            key=key,
        )


def sample_budget() -> int:
    """Most samples one frame may plan: ``HWSIM_MAX_SAMPLES`` or :data:`DEFAULT_MAX_SAMPLES`."""
    env = value(SAMPLE_ENV_VAR)
    return DEFAULT_MAX_SAMPLES if env is None else env
