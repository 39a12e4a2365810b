"""Running a sweep on Dask: a local cluster bound to 127.0.0.1, or an existing scheduler.

# Ref: shared/docs/design.md sections 8 and 9 (sweeps on Dask, rows in SQLite).

The driver computes every run's key, skips keys the database already has, submits the
rest as one Dask task each and writes each result the moment it arrives, in its own
transaction (:class:`hwsim.sweep.db.RunsDB`).  A run that raises is caught on the worker
and comes back as an ``error`` row, so one bad run never stops the sweep.  A worker
that dies mid-task (killed, out of memory) is replaced by its nanny and the scheduler
reruns the task elsewhere, up to :data:`ALLOWED_FAILURES` times; past that the run is
recorded as failed with Dask's ``KilledWorker`` error.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.errors import HwsimError, InputError
from hwsim.sweep.db import RunsDB
from hwsim.sweep.spec import RunSpec, Sweep, build_run, code_version, run_key, technology_of

__all__ = [
    "ALLOWED_FAILURES",
    "SweepSummary",
    "execute_run",
    "local_client",
    "connect",
    "run_sweep",
    "image_digest",
]

#: How many workers may die holding one task before the run is recorded as failed.
ALLOWED_FAILURES = 3


@dataclass
class SweepSummary:
    """What a sweep did: runs in the file, already in the database, ok, failed, time."""

    total: int
    skipped: int
    ok: int
    failed: int
    wall_seconds: float
    db: str


def image_digest(image: np.ndarray) -> str:
    """SHA-256 of an image's shape, dtype and bytes: equal digests mean identical bits."""
    digest = hashlib.sha256(f"{image.shape}{image.dtype.str}".encode())
    digest.update(np.ascontiguousarray(image).tobytes())
    return digest.hexdigest()


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def execute_run(run: RunSpec, key: str, out_dir: str | None = None) -> dict[str, Any]:
    """Render one run; return its database row (never raises for a failed render).

    Runs on a Dask worker.  With ``out_dir`` the run's ``image.npy``, ``image.png`` and
    ``stats.json`` are also written to ``out_dir/<key[:16]>`` (what ``hwsim report``
    reads), with ``sweep.json``: the run's key, parameters and architecture overrides.
    """
    from hwsim.fidelity import render
    from hwsim.output import stats_plain, write_render

    p = run.values
    row: dict[str, Any] = {
        "key": key,
        "label": run.label(),
        "params": p,
        "arch": p.get("arch"),
        "fidelity": p.get("fidelity"),
        "code_version": code_version(),
        "worker": _worker_name(),
        "worker_pid": os.getpid(),
        "started_at": _now(),
    }
    try:
        scene, arch, fidelity, overrides = build_run(run)
        row.update(scene=scene.name, volume=scene.volume.describe(), mode=scene.render.mode)
        result = render(
            scene,
            fidelity=fidelity,
            arch=arch,
            timing_only=p.get("timing_only", False),
            technology=technology_of(run),
        )
        stats = stats_plain(result)
        row.update(
            status="ok",
            arch=result.arch,
            fidelity=result.fidelity,
            stats=stats,
            image_sha256=None if result.image is None else image_digest(result.image),
            **{
                k: stats[k]
                for k in (
                    "samples",
                    "rays",
                    "cycles",
                    "clock_hz",
                    "frame_seconds",
                    "samples_per_second",
                    "wall_seconds",
                    "wall_samples_per_second",
                )
            },
        )
        if stats.get("energy"):  # hwsim.energy, priced in the machine's own node
            row.update(
                technology=stats["technology"]["name"],
                energy_joules=stats["energy"]["total_joules"],
                energy_per_sample_joules=stats["energy"]["per_sample_joules"],
                area_mm2=stats["area"]["total_mm2"],
            )
        if out_dir is not None:
            folder = Path(out_dir) / key[:16]
            write_render(result, folder)
            sweep_facts = {"key": key, "params": p, "arch_overrides": overrides}
            (folder / "sweep.json").write_text(json.dumps(sweep_facts, indent=2) + "\n")
            row["run_dir"] = str(folder)
    except Exception as exc:  # recorded, not raised: one bad run must not stop a sweep
        text = str(exc) if isinstance(exc, HwsimError) else f"{type(exc).__name__}: {exc}"
        row.update(status="error", error=text)
    row["finished_at"] = _now()
    return row


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
        # (hwsim.threads.frame_threads), unless the user chose otherwise.
        "distributed.nanny.pre-spawn-environ.HWSIM_THREADS": os.environ.get("HWSIM_THREADS", "1"),
    }
    with dask.config.set(settings):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
            worker_dashboard_address="127.0.0.1:0",
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


def run_sweep(
    sweep: Sweep,
    db: RunsDB,
    client: Any,
    *,
    out_dir: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SweepSummary:
    """Run every run of ``sweep`` whose key ``db`` does not hold yet.

    Parameters
    ----------
    sweep : Sweep
        The validated sweep file.
    db : RunsDB
        Where rows go, one transaction per finished run.
    client : distributed.Client
        The Dask client to submit to.
    out_dir : str or Path, optional
        Also write each run's render folder under it.
    progress : callable, optional
        ``progress(done, total)`` after each finished run (total = runs submitted).
    """
    from distributed import as_completed

    start = time.perf_counter()
    keyed: dict[str, RunSpec] = {}
    for run in sweep.runs:
        keyed.setdefault(run_key(run), run)  # identical configurations run once
    done_keys = db.finished_keys()
    pending = [(k, r) for k, r in keyed.items() if k not in done_keys]
    out = str(Path(out_dir).resolve()) if out_dir is not None else None
    futures = {
        client.submit(execute_run, run, key, out, pure=False): (key, run) for key, run in pending
    }
    ok = failed = 0
    if progress is not None and pending:
        progress(0, len(pending))
    for n, future in enumerate(as_completed(futures), start=1):
        key, run = futures.pop(future)
        try:
            row = future.result()
        except Exception as exc:  # the task itself failed: worker lost too often, cancelled
            row = {
                "key": key,
                "label": run.label(),
                "params": run.values,
                "status": "error",
                "error": f"{type(exc).__name__}: {exc}",
                "code_version": code_version(),
                "finished_at": _now(),
            }
        future.release()
        db.insert(row)
        ok += row["status"] == "ok"
        failed += row["status"] != "ok"
        if progress is not None:
            progress(n, len(pending))
    return SweepSummary(
        total=len(keyed),
        skipped=len(keyed) - len(pending),
        ok=ok,
        failed=failed,
        wall_seconds=time.perf_counter() - start,
        db=str(db.path),
    )
