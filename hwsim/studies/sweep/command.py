"""``hwsim sweep SWEEP.toml``: load, run on Dask, write rows, print a summary."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError

__all__ = ["sweep_command"]


def sweep_command(args: argparse.Namespace, progress_bar: Any) -> int:
    """Run the sweep the parsed ``args`` describe; exit status 1 if any run failed."""
    from hwsim.core.cluster import check_address, connect, local_client
    from hwsim.core.paths import FILE, FOLDER, plan_outputs
    from hwsim.studies.sweep.db import RunsDB, check_ours
    from hwsim.studies.sweep.runner import run_sweep
    from hwsim.studies.sweep.spec import load_sweep

    if not 1 <= args.workers <= 256:
        raise InputError(f"{args.workers} is out of range", key="--workers", allowed="1 .. 256")
    sweep = load_sweep(args.file)
    outputs = [("--db", args.db, FILE), ("--out", args.out or None, FOLDER)]
    plan_outputs([("SWEEP.toml", args.file)], outputs)  # never onto the sweep file
    check_ours(Path(args.db))
    if args.scheduler:
        check_address(args.scheduler)
    with contextlib.ExitStack() as stack:
        if args.scheduler:  # reached before the database is opened or changed
            client = stack.enter_context(connect(args.scheduler))
        else:
            client = stack.enter_context(local_client(args.workers))
        db = stack.enter_context(RunsDB(args.db))
        with progress_bar(args.quiet, "sweep") as progress:
            summary = run_sweep(
                sweep,
                db,
                client,
                out_dir=args.out,
                progress=progress,
                retry_failed=args.retry_failed,
            )
    if not args.quiet:
        print(
            f"{summary.total} runs: {summary.skipped} already in {summary.db}, "
            f"{summary.ok} ok, {summary.failed} failed, in {summary.wall_seconds:.1f} s"
        )
    if summary.failed:
        print(
            f"hwsim: {summary.failed} run(s) failed; their errors are in {summary.db} "
            "(table runs, column error); --retry-failed reruns them",
            file=sys.stderr,
        )
        return 1
    return 0
