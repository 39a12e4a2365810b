"""Dask clusters for hwsim's distributed work: sweeps (:mod:`hwsim.studies.sweep`) and frames split
across workers (:mod:`hwsim.run.frame_split`).

# Ref: shared/docs/design.md sections 8 and 9 (sweeps on Dask).

A local cluster binds to 127.0.0.1 only, with one single-thread worker process per core
asked; an existing cluster is reached by its scheduler's address.  A worker that dies
holding a task is replaced by its nanny and the scheduler reruns the task elsewhere, up to
:data:`ALLOWED_FAILURES` times.
"""

from __future__ import annotations

import contextlib
import logging
import resource
from collections.abc import Iterator
from typing import Any

from hwsim.core import env, interrupt
from hwsim.core.errors import InputError

__all__ = [
    "ALLOWED_FAILURES",
    "local_client",
    "connect",
    "check_address",
    "client_for",
    "peak_rss_bytes",
    "reset_peak_rss",
]

#: How many workers may die holding one task before the task is failed.
ALLOWED_FAILURES = 3


@contextlib.contextmanager
def local_client(workers: int) -> Iterator[Any]:
    """A Dask client on a ``LocalCluster`` of ``workers`` single-thread processes.

    Everything listens on 127.0.0.1 only; the dashboard is off.
    """
    import dask
    from distributed import Client, LocalCluster

    settings = {
        "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
        # Dask's nannies export MALLOC_TRIM_THRESHOLD_=65536 to their workers; that fixes
        # glibc's mmap threshold at 128 KiB, so every NumPy temporary of a render is a
        # fresh mmap and page faults: a 96^3 functional render took 3x longer.
        "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
        # One worker per core already: each render runs its frame on one thread
        # (hwsim.core.threads.frame_threads), unless the user chose otherwise.
        "distributed.nanny.pre-spawn-environ.HWSIM_THREADS": str(env.value("HWSIM_THREADS") or 1),
    }
    with dask.config.set(settings):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
            worker_dashboard_address="127.0.0.1:0",
            preload=[interrupt.__name__],  # the workers ignore SIGINT
            silence_logs=logging.ERROR,
        )
        try:
            with Client(cluster) as client:
                yield client
        finally:
            cluster.close()


def check_address(address: str) -> None:
    """``[tcp://]host:port`` with a port in 1 .. 65535, or a one-line input error."""
    rest = address.split("://", 1)[-1]
    host, _, port = rest.rpartition(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise InputError(
            f"{address!r} has no port",
            source=address,
            key="--scheduler",
            allowed="tcp://HOST:PORT with PORT in 1 .. 65535",
        )


@contextlib.contextmanager
def connect(address: str) -> Iterator[Any]:
    """A Dask client on an existing scheduler (``tcp://host:port``)."""
    from distributed import Client

    check_address(address)
    try:
        client = Client(address, timeout="5s")
    except (OSError, TimeoutError) as exc:
        raise InputError(
            f"cannot reach the scheduler: {exc}", source=address, key="--scheduler"
        ) from None
    with client:
        yield client


@contextlib.contextmanager
def client_for(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A client on an existing scheduler when ``scheduler`` is given, else on a local
    cluster of ``workers`` processes."""
    if scheduler is not None:
        with connect(scheduler) as client:
            yield client
    else:
        with local_client(int(workers or 1)) as client:
            yield client


def reset_peak_rss() -> None:
    """Restart the kernel's peak-RSS mark of this process (Linux ``clear_refs`` 5), so a
    long-lived worker reports each band's peak rather than its lifetime's."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass


def peak_rss_bytes() -> int:
    """This process's peak resident memory since :func:`reset_peak_rss` (``VmHWM``), or
    over its lifetime where that is not available."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
