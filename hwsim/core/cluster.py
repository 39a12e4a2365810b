"""Dask clusters for hwsim's distributed work: sweeps (:mod:`hwsim.studies.sweep`) and frames split
across workers (:mod:`hwsim.run.frame_split`).

# Ref: shared/docs/design.md sections 8 and 9 (sweeps on Dask).

A local cluster binds to 127.0.0.1 only, with one single-thread worker process per core
asked; an existing cluster is reached by its scheduler's address.  Its scheduler, nannies
and workers keep their scratch files in a fresh directory of their own under the system
temp dir (``hwsim-dask-*``), removed at close, or by the next cluster if its process was
killed.  Dask's shared ``dask-scratch-space`` holds what killed workers left behind, and
Dask purging that as a cluster starts on a busy machine took long enough for it to warn
("Creating scratch directories is taking a surprisingly long time"; under pytest's
warnings-as-errors, a failed start); hwsim's own clean-up runs outside that timed step.
The dashboards listen on port 0 (no "Port 8787 is already in use"), and the workers log
as the parent does (:mod:`hwsim.core.logs`).

A worker that dies holding a task is replaced by its nanny and the scheduler reruns the
task elsewhere, up to :data:`ALLOWED_FAILURES` times.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import resource
import shutil
import socket
import struct
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from hwsim.core import env, interrupt
from hwsim.core.errors import InputError

__all__ = [
    "ALLOWED_FAILURES",
    "local_client",
    "connect",
    "check_address",
    "heartbeat",
    "scheduler_workers",
    "scheduler_timeout",
    "client_for",
    "peak_rss_bytes",
    "reset_peak_rss",
]

#: How many workers may die holding one task before the task is failed.
ALLOWED_FAILURES = 3


@contextlib.contextmanager
def local_client(workers: int) -> Iterator[Any]:
    """A Dask client on a ``LocalCluster`` of ``workers`` single-thread processes.

    Everything listens on 127.0.0.1 only (dashboards on free ports); scratch files go to
    a private temporary directory removed at close; logging follows
    :func:`hwsim.core.logs.verbosity` in every process.
    """
    import dask
    from distributed import Client, LocalCluster

    from hwsim.core import logs

    logs.reapply()  # distributed's first import set its own loggers' levels
    verbose = logs.verbosity()
    settings = {
        "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
        # Dask's nannies export MALLOC_TRIM_THRESHOLD_=65536 to their workers; that fixes
        # glibc's mmap threshold at 128 KiB, so every NumPy temporary of a render is a
        # fresh mmap and page faults: a 96^3 functional render took 3x longer.
        "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
        logs.DASK_KEY: verbose,  # read in each worker by the preload, logs.dask_setup
    }
    with _scratch_directory() as scratch, dask.config.set(settings):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
            worker_dashboard_address="127.0.0.1:0",
            local_directory=scratch,
            scheduler_kwargs={"local_directory": scratch},
            preload=[logs.__name__, interrupt.__name__],  # interrupt: workers ignore SIGINT
            # One worker per core already: each render runs its frame on one thread
            # (hwsim.core.threads.frame_threads), unless the user chose otherwise. A
            # nanny argument, set inside each worker process: pre-spawn-environ would
            # also write it into this process's environment and leave it there (an API
            # user's later renders in the same process ran on one thread).
            env={"HWSIM_THREADS": str(env.value("HWSIM_THREADS") or 1)},
            silence_logs=False if verbose else logging.ERROR,
        )
        try:
            with Client(cluster) as client:
                yield client
        finally:
            cluster.close()


#: Name prefix of a local cluster's scratch directory and of its lock file beside it.
_SCRATCH_PREFIX = "hwsim-dask-"


@contextlib.contextmanager
def _scratch_directory() -> Iterator[str]:
    """A fresh directory for one local cluster's scratch files, removed at close.

    Its lock file beside it (``<dir>.lock``, locked while the cluster runs) lets a later
    cluster remove what a killed process left: :func:`_remove_orphans`.
    """
    base = Path(tempfile.gettempdir())
    _remove_orphans(base)
    fd, name = tempfile.mkstemp(prefix=_SCRATCH_PREFIX, suffix=".lock", dir=base)
    lock = Path(name)
    path = lock.with_suffix("")
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        path.mkdir(exist_ok=True)
        yield str(path)
    finally:
        shutil.rmtree(path, ignore_errors=True)
        lock.unlink(missing_ok=True)
        os.close(fd)


def _remove_orphans(base: Path) -> None:
    """Remove the scratch directories whose lock nobody holds (their process is gone)."""
    for lock in base.glob(f"{_SCRATCH_PREFIX}*.lock"):
        try:
            fd = os.open(lock, os.O_RDWR)
        except OSError:  # removed meanwhile, or another user's
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held: that cluster is running
            os.close(fd)
            continue
        try:
            shutil.rmtree(lock.with_suffix(""), ignore_errors=True)
            lock.unlink(missing_ok=True)
        finally:
            os.close(fd)


#: Address schemes ``--scheduler`` accepts: Dask's TCP transport, what ``dask scheduler``
#: listens on by default.  ``tls://`` needs certificates hwsim has no options for,
#: ``inproc://`` reaches only a scheduler inside this process, and ``ucx://`` / ``ws://``
#: need extras this install does not have, so each is refused by name before connecting.
SCHEMES = ("tcp",)
_ALLOWED_ADDRESS = "tcp://HOST:PORT (or HOST:PORT) with PORT in 1 .. 65535"

#: Seconds between two liveness checks of the scheduler while waiting for results.
HEARTBEAT_SECONDS = 5.0


def check_address(address: str) -> None:
    """``[tcp://]host:port`` with a port in 1 .. 65535, or a one-line input error naming
    ``--scheduler`` and the allowed form (an unsupported scheme is named)."""
    scheme, sep, rest = address.partition("://")
    if sep and scheme.lower() not in SCHEMES:
        raise InputError(
            f"unsupported address scheme {scheme + '://'!r} in {address!r}",
            key="--scheduler",
            allowed=_ALLOWED_ADDRESS,
        )
    host, _, port = (rest if sep else address).rpartition(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise InputError(f"{address!r} has no port", key="--scheduler", allowed=_ALLOWED_ADDRESS)


def scheduler_timeout() -> float:
    """Seconds a scheduler has to answer: Dask's ``distributed.comm.timeouts.connect``
    (environment ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT``, default 30 s)."""
    import dask
    import distributed  # noqa: F401  (its import adds its defaults to dask.config)
    from dask.utils import parse_timedelta

    value = dask.config.get("distributed.comm.timeouts.connect")
    try:
        seconds = float(parse_timedelta(value, default="seconds"))
    except (TypeError, ValueError):
        seconds = -1.0
    if not 0 < seconds <= 3600:
        raise InputError(
            f"{value!r} is not a duration",
            key="DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT",
            allowed="a duration in 0 .. 3600 s, e.g. 10s",
        )
    return seconds


@contextlib.contextmanager
def connect(address: str) -> Iterator[Any]:
    """A Dask client on an existing scheduler (``tcp://host:port``).

    The scheme is checked before any connection (:func:`check_address`).  Connecting,
    Dask's handshake and the first exchange with the scheduler must all finish within
    :func:`scheduler_timeout` seconds, even against a peer that accepts and says nothing
    or says garbage: the port is first probed with a plain socket that reads the peer's
    handshake frame (a Dask scheduler speaks first; its frame is small), then the client
    is built in a thread the caller waits for with a deadline (Dask's own ``timeout``
    does not cover a handshake that never comes).  Failures are one-line input errors.
    """
    from hwsim.core import logs

    logs.reapply()  # distributed's first import set its own loggers' levels
    check_address(address)
    if "://" not in address:
        address = f"tcp://{address}"
    seconds = scheduler_timeout()
    deadline = time.monotonic() + seconds
    _probe(address, seconds, deadline)
    client = _client_within(address, seconds, deadline)
    with client:
        yield client


def _silent(address: str, seconds: float) -> InputError:
    return InputError(
        f"scheduler at {address} did not answer within {seconds:g} s", key="--scheduler"
    )


def _garbled(address: str, why: str) -> InputError:
    return InputError(
        f"scheduler at {address} did not answer as a Dask scheduler ({why})", key="--scheduler"
    )


def _probe(address: str, seconds: float, deadline: float) -> None:
    """Connect with a plain socket and read the peer's first Dask frame header within the
    deadline: a silent or garbling peer is refused before Dask allocates what it claims."""
    host, _, port = address.partition("://")[2].rpartition(":")
    host = host.strip("[]")
    try:
        with socket.create_connection((host, int(port)), timeout=seconds) as sock:
            size = struct.unpack("<Q", _recv_exact(sock, 8, deadline, address, seconds))[0]
            if not 16 <= size <= _MAX_HANDSHAKE:
                raise _garbled(address, f"a first message of {size} bytes")
            head = _recv_exact(sock, size, deadline, address, seconds)
    except TimeoutError:
        raise _silent(address, seconds) from None
    except OSError as exc:
        raise InputError(
            f"cannot reach the scheduler at {address}: {exc.strerror or exc}", key="--scheduler"
        ) from None
    if not _is_handshake(head):
        raise _garbled(address, "its first message is not a Dask handshake")


def _is_handshake(head: bytes) -> bool:
    """Whether ``head`` (a first message's frames) is Dask's handshake: a msgpack map
    naming the peer's compression and Python version."""
    import msgpack
    from distributed.protocol.utils import unpack_frames

    try:
        n_frames = struct.unpack("<Q", head[:8])[0]
        if not 1 <= n_frames <= 64:
            return False
        frames, _ = unpack_frames(head, partial=True)
        for frame in frames:
            message = msgpack.loads(frame, raw=False)
            if isinstance(message, dict) and {"compression", "python"} <= message.keys():
                return True
    except Exception:  # garbage of any shape
        return False
    return False


#: A Dask handshake is a few hundred bytes; a peer claiming more is not a scheduler.
_MAX_HANDSHAKE = 1 << 20


def _recv_exact(sock: socket.socket, n: int, deadline: float, address: str, seconds: float):
    data = bytearray()
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise _silent(address, seconds)
        sock.settimeout(left)
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise _garbled(address, "it closed the connection")
        data += chunk
    return bytes(data)


def _client_within(address: str, seconds: float, deadline: float) -> Any:
    """``distributed.Client(address)`` built in a daemon thread, waited for until the
    deadline; a client that comes too late is closed by that thread."""
    from distributed import Client

    box: dict[str, Any] = {}
    late = threading.Event()

    def build() -> None:
        try:
            client = Client(address, timeout=seconds, set_as_default=False)
        except BaseException as exc:  # reported by the waiting caller
            box["error"] = exc
            return
        box["client"] = client
        if late.is_set():
            client.close(timeout=seconds)

    thread = threading.Thread(target=build, name="hwsim-connect", daemon=True)
    thread.start()
    thread.join(max(0.0, deadline - time.monotonic()) + 1.0)
    if thread.is_alive():
        late.set()
        raise _silent(address, seconds)
    if "error" in box:
        exc = box["error"]
        if isinstance(exc, (TimeoutError, OSError)):
            raise _silent(address, seconds) from None
        raise _garbled(address, f"{type(exc).__name__}: {exc}"[:200]) from None
    return box["client"]


def scheduler_workers(client: Any) -> dict[str, int]:
    """The scheduler's workers and their threads, asked within :func:`scheduler_timeout`
    seconds: a silent scheduler is a one-line input error."""
    seconds = scheduler_timeout()
    try:
        return dict(client.nthreads(callback_timeout=seconds))
    except Exception:  # a timeout, a closed comm
        raise _stopped(client, seconds) from None


def _stopped(client: Any, seconds: float) -> InputError:
    where = getattr(client.scheduler, "address", "?")
    return InputError(
        f"scheduler at {where} stopped answering (no reply within {seconds:g} s)",
        key="--scheduler",
    )


def heartbeat(client: Any) -> Callable[[], None]:
    """A check to call while waiting for results: every :data:`HEARTBEAT_SECONDS` it asks
    the scheduler for its identity and raises a one-line input error when no answer
    comes within :func:`scheduler_timeout` seconds (a scheduler gone silent mid-run)."""
    seconds = scheduler_timeout()
    last = [time.monotonic()]

    def check() -> None:
        if time.monotonic() - last[0] < HEARTBEAT_SECONDS:
            return
        try:
            client.sync(client.scheduler.identity, callback_timeout=seconds)
        except Exception:  # a timeout, a closed comm: the scheduler is gone
            raise _stopped(client, seconds) from None
        last[0] = time.monotonic()

    return check


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
