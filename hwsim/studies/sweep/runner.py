"""Running a sweep on Dask: a local cluster bound to 127.0.0.1, or an existing scheduler.

# Ref: shared/docs/design.md sections 8 and 9 (sweeps on Dask, rows in SQLite).

The driver walks the product a batch at a time (twice the workers' threads): it computes
each run's key as it goes, skips keys the database already has (one query per batch),
submits the rest as one Dask task each, at most a batch in flight, and writes each result
the moment it arrives, in its own transaction (:class:`hwsim.studies.sweep.db.RunsDB`);
a product of a million runs starts writing rows at once, in bounded memory.  While it
waits the scheduler is asked every few seconds whether it still answers
(:func:`hwsim.core.cluster.heartbeat`): a scheduler gone silent ends the sweep with one
line, the rows already written kept.  With ``--retry-failed`` a failed row is replaced
in the transaction that writes its new result.  A run that raises is caught on the worker
and comes back as an ``error`` row, so one bad run never stops the sweep.  A worker
that dies mid-task (killed, out of memory) is replaced by its nanny and the scheduler
reruns the task elsewhere, up to :data:`ALLOWED_FAILURES` times; past that the run is
recorded as failed with Dask's ``KilledWorker`` error.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core import env
from hwsim.core.cluster import (
    ALLOWED_FAILURES,
    connect,
    heartbeat,
    local_client,
    scheduler_timeout,
    scheduler_workers,
)
from hwsim.core.errors import HwsimError, InputError
from hwsim.core.paths import display_path, display_text, write_text_atomic
from hwsim.studies.sweep.db import RunsDB
from hwsim.studies.sweep.spec import RunSpec, Sweep, build_run, code_version, run_key, technology_of

__all__ = [
    "ALLOWED_FAILURES",
    "SweepSummary",
    "execute_run",
    "local_client",
    "connect",
    "run_sweep",
    "image_digest",
]


@dataclass
class SweepSummary:
    """What a sweep did: runs in the file, already in the database, ok, failed, time;
    ``rows`` (filled by :func:`hwsim.sweep`, which returns it as ``hwsim.SweepResult``):
    one dict per run of this sweep (docs/sweeps.md columns; ``params`` and ``stats``
    decoded), in the database's order."""

    total: int
    skipped: int
    ok: int
    failed: int
    wall_seconds: float
    db: str
    rows: list[dict[str, Any]] = field(default_factory=list)


def image_digest(image: np.ndarray) -> str:
    """SHA-256 of an image's shape, dtype and bytes: equal digests mean identical bits."""
    digest = hashlib.sha256(f"{image.shape}{image.dtype.str}".encode())
    digest.update(np.ascontiguousarray(image).tobytes())
    return digest.hexdigest()


#: Runs this process has started: the first pays for the imports and the JIT compile.
_RUNS_IN_PROCESS = itertools.count()


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
    from hwsim.run.fidelity import render
    from hwsim.run.output import stats_plain, write_render

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
        "includes_compile": next(_RUNS_IN_PROCESS) == 0,  # its wall time is not warm
    }
    try:
        scene, arch, fidelity, overrides = build_run(run)
        volume = display_path(scene.volume.describe())  # a file or a phantom's spec
        row.update(scene=scene.name, volume=volume, mode=scene.render.mode)
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
            write_text_atomic(folder / "sweep.json", json.dumps(sweep_facts, indent=2) + "\n")
            row["run_dir"] = display_path(folder)
    except Exception as exc:  # recorded, not raised: one bad run must not stop a sweep
        text = str(exc) if isinstance(exc, HwsimError) else f"{type(exc).__name__}: {exc}"
        text = display_text(text)  # the paths it names, as display_path writes them
        row.update(status="error", error=text)
    row["finished_at"] = _now()
    return row


def run_sweep(
    sweep: Sweep,
    db: RunsDB,
    client: Any,
    *,
    out_dir: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    retry_failed: bool = False,
    keys: set[str] | None = None,
) -> SweepSummary:
    """Run every run of ``sweep`` whose key ``db`` does not hold yet, streaming.

    Keys are computed as the product is walked, a batch at a time; each batch is
    checked against ``db`` and its new runs submitted, with at most twice the workers'
    threads in flight, so memory stays bounded whatever the product's size.

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
        ``progress(done, total)`` as runs finish or are skipped (total = the product).
    retry_failed : bool
        Rerun the runs recorded as failed; each failed row is replaced in the
        transaction that writes its new result (never deleted first).
    keys : set, optional
        Filled with the key of every run of the sweep.
    """
    start = time.perf_counter()
    out = str(Path(out_dir).resolve()) if out_dir is not None else None
    flow = _Flow(client, db, sweep.size, progress, retry_failed)
    flow.report()
    task = env.Carried(execute_run, env.settings(HWSIM_THREADS="1"))  # not the worker's own
    for batch in _batches(_keyed(sweep.runs), flow.limit):
        statuses = db.statuses(key for key, _ in batch)
        for key, run in batch:
            if keys is not None:
                keys.add(key)
            if flow.should_skip(key, statuses.get(key)):
                flow.skipped += 1
                flow.report()
                continue
            flow.submit(client.submit(task, run, key, out, pure=False), key, run)
            while len(flow.futures) >= flow.limit:
                flow.collect()
    while flow.futures:
        flow.collect()
    return SweepSummary(
        total=sweep.size,
        skipped=flow.skipped,
        ok=flow.ok,
        failed=flow.failed,
        wall_seconds=time.perf_counter() - start,
        db=str(db.path),
    )


def _keyed(runs: Iterable[RunSpec]) -> Iterator[tuple[str, RunSpec]]:
    """``(run_key(run), run)`` for each run, computed as it is asked for."""
    for run in runs:
        yield run_key(run), run


def _batches(items: Iterator[Any], size: int) -> Iterator[list[Any]]:
    """``items`` in lists of ``size`` (the last one shorter), read as they are asked for."""
    while batch := list(itertools.islice(items, size)):
        yield batch


class _Flow:
    """A sweep's runs in flight: submitted futures, their rows written as they finish."""

    def __init__(self, client, db, total, progress, retry_failed) -> None:
        from distributed import as_completed

        self.db, self.total, self.progress = db, total, progress
        self.retry_failed = retry_failed
        self.limit = 2 * max(1, sum(scheduler_workers(client).values()))
        self.alive = heartbeat(client)
        self.seconds = scheduler_timeout()
        self.futures: dict[Any, tuple[str, RunSpec]] = {}
        self.queue = as_completed()
        self.retried: set[str] = set()  # failed keys rerun by this sweep (bounded by them)
        self.skipped = self.ok = self.failed = 0

    def should_skip(self, key: str, status: str | None) -> bool:
        """A key in flight, already rerun, or with a row (a failed one unless retrying)."""
        if key in self.retried or any(k == key for k, _ in self.futures.values()):
            return True
        if status == "error" and self.retry_failed:
            self.retried.add(key)
            return False
        return status is not None

    def submit(self, future: Any, key: str, run: RunSpec) -> None:
        self.futures[future] = (key, run)
        self.queue.add(future)

    def report(self) -> None:
        if self.progress is not None:
            self.progress(self.skipped + self.ok + self.failed, self.total)

    def collect(self) -> None:
        """Wait for finished runs (checking the scheduler answers) and write their rows."""
        while not self.queue.has_ready():
            self.alive()
            time.sleep(0.05)
        for future in self.queue.next_batch(block=False):
            key, run = self.futures.pop(future)
            self.db.insert(self._row(future, key, run), replace_failed=key in self.retried)
            future.release()
            self.report()

    def _row(self, future: Any, key: str, run: RunSpec) -> dict[str, Any]:
        try:
            row = future.result(timeout=self.seconds)
        except TimeoutError:  # finished, but its result never came: the scheduler is gone
            raise InputError(
                f"a finished run's result did not arrive within {self.seconds:g} s",
                key="--scheduler",
            ) from None
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
        self.ok += row["status"] == "ok"
        self.failed += row["status"] != "ok"
        return row
