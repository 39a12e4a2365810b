"""Running a sweep on Dask: a local cluster bound to 127.0.0.1, or an existing scheduler.

# Ref: shared/docs/design.md sections 8 and 9 (sweeps on Dask, rows in SQLite).

The driver computes every run's key, skips keys the database already has, submits the
rest as one Dask task each and writes each result the moment it arrives, in its own
transaction (:class:`hwsim.studies.sweep.db.RunsDB`).  A run that raises is caught on the worker
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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.cluster import ALLOWED_FAILURES, connect, local_client
from hwsim.core.errors import HwsimError
from hwsim.core.paths import display_path, display_text
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
            (folder / "sweep.json").write_text(json.dumps(sweep_facts, indent=2) + "\n")
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
