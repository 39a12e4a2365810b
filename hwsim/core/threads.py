"""Threads per frame: how many cores one frame's compiled kernels use.

The golden ray walk and the functional rung's composite kernel are compiled with the GIL
released (numba ``nogil``); a frame splits its rays (or a step's samples) into
independent parts run by a small pool of Python threads, so the result is bit-identical
for any thread count.  Plain threads rather than numba's ``parallel=True``: numba's
default ``workqueue`` threading layer aborts when two threads enter a parallel region at
once, which Dask worker threads would do.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

from hwsim.core import env
from hwsim.core.errors import InputError

__all__ = ["THREADS_ENV_VAR", "frame_threads", "join_pools", "pool", "using"]

#: Environment variable: threads per frame (:func:`frame_threads`).
THREADS_ENV_VAR = "HWSIM_THREADS"

_POOLS: dict[int, ThreadPoolExecutor] = {}


def frame_threads() -> int:
    """Threads one frame's compiled kernels use: ``HWSIM_THREADS``, else every core this
    process may run on (sweeps start their workers with one each)."""
    threads = env.value(THREADS_ENV_VAR)
    return max(1, len(os.sched_getaffinity(0))) if threads is None else threads


def pool(threads: int) -> ThreadPoolExecutor:
    """This process's pool of ``threads`` frame threads (made once, reused)."""
    found = _POOLS.get(threads)
    if found is None:
        found = _POOLS[threads] = ThreadPoolExecutor(threads, thread_name_prefix="hwsim-frame")
    return found


def join_pools() -> None:
    """Cancel the frame threads' queued work and wait for the running work to end (after
    an interrupt: each part checks :func:`hwsim.core.interrupt.check` between steps)."""
    while _POOLS:
        _, found = _POOLS.popitem()
        found.shutdown(wait=True, cancel_futures=True)


@contextmanager
def using(threads: int | None) -> Iterator[None]:
    """Frames inside the block use ``threads`` threads (None: unchanged); restored after."""
    if threads is None:
        yield
        return
    if not 1 <= threads <= env.MAX_THREADS:
        raise InputError(
            f"{threads} is out of range", key="--threads", allowed=f"1 .. {env.MAX_THREADS}"
        )
    old = os.environ.get(THREADS_ENV_VAR)
    os.environ[THREADS_ENV_VAR] = str(threads)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(THREADS_ENV_VAR, None)
        else:
            os.environ[THREADS_ENV_VAR] = old
