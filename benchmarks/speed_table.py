"""Issue 18's speed table, every row measured in one run: hwsim against the software users
would pick instead (VTK, VolPack), the cycle rung's speed on every machine, the
timing-only transaction rung against it, a 512^3 cycle frame's peak memory, and what a
second core buys.

Usage::

    .venv/bin/python benchmarks/speed_table.py [--rows NAME ...] [--sizes 128 256]
        [--memory-size 512] [--repeats 3] [--out benchmarks/results/speed-table.json]

``hwsim bench`` runs the same rows (this module is its harness).  This module plans and
runs the rows; ``speed_rows.py`` measures them and ``speed_report.py`` prints every row
and every case in it (each machine and size, each rung) against its goal, with the load
average before and after the row.  Each row times the
things it compares in alternation (A, B, A, B, ...), so a change of machine load falls on
both; the load average is recorded before and after every row.  Headline figures use
**one thread** for hwsim and for VTK (``HWSIM_THREADS=1``, ``SetNumberOfThreads(1)``);
the two-thread figures sit beside them.  Benchmarks assert nothing (conventions item 11).

A row that needs more than the run install (:data:`REQUIRES`: VTK from the ``bench``
extra, VolPack from apt, the shared data) is checked before any row is measured and,
when that is missing, ``skipped`` with a one-line reason naming what to install;
``--no-vtk`` skips the VTK rows.  A row that raises is ``failed`` with its error in one
line and the other rows still run (the exit status is then 1).

======================  ========================================================  =======
row                     value                                                     goal
======================  ========================================================  =======
golden_vs_vtk_first     VTK first frame s / golden first frame s: real CT, 256^2  >= 0.5
golden_vs_vtk_rotation  the same over later frames of a 5-degree rotation         >= 0.1
functional_vs_volpack   VolPack s/frame / functional (volumepro500) s/frame       >= 0.1
functional_vs_golden    golden s / functional s, the machine's sample positions   >= 2
cycle_samples_per_s     the slowest machine's cycle-rung samples per second       >= 5 M
timing_only_vs_cycle    the smallest cycle s / timing-only transaction s          >= 10
cycle_512_peak_bytes    the largest peak resident set of a 512^3 cycle frame      <= 1.5 G
threads_2_vs_1          the smallest 1-thread s / 2-thread s (golden, functional) >= 1.7
======================  ========================================================  =======

The golden and VTK frames: ``../shared/data/ct_cranium.nrrd`` (256 x 256 x 108 int16), the
``ct`` preset, composite with one-light Phong (the built-in ``head`` scene's view and
material), 256 x 256, VTK's built-in early ray termination (accumulated opacity 0.9922)
given to the golden renderer too.  A *first frame* is everything after the process has
started and imported: golden reads and decodes the file and renders (its gradients and
block ranges computed for the new volume); VTK builds its pipeline on the decoded array
and renders its first frame (which computes and encodes its gradients).  A *later frame*
is the median of frames 2..N of a rotation by 5 degrees a frame, each renderer keeping
its per-volume data.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from benchmarks.speed_report import format_rows, load_text
from benchmarks.speed_rows import (
    CT,
    MACHINES,
    _ct_scene,
    cycle_512_peak,
    cycle_and_timing_only,
    functional_vs_golden,
    functional_vs_volpack,
    golden_vs_vtk_first,
    golden_vs_vtk_rotation,
    threads_2_vs_1,
)
from hwsim.studies.bench import TABLE_GOALS as GOALS
from hwsim.studies.bench import one_line

__all__ = [
    "CT",
    "MACHINES",
    "REQUIRES",
    "ROWS",
    "VTK_ROWS",
    "_ct_scene",
    "format_rows",
    "load_text",
    "main",
    "plan",
    "run",
    "skipped",
]

ROWS = tuple(GOALS)  # the table's rows, in order


# ----------------------------------------------------------------- what rows need


def _needs_vtk() -> str | None:
    from benchmarks.vtk_reference import vtk_missing

    return vtk_missing()


def _needs_ct() -> str | None:
    return None if CT.is_file() else f"needs {CT} (the shared data beside the clone)"


def _needs_volpack() -> str | None:
    from benchmarks.volpack_reference import volpack_available

    return volpack_available()


#: What a row needs beyond the run install (``pip install -e .[run]``), each a check that
#: returns why it is missing (one line naming what to install) or None.  The other rows
#: need nothing more (``threads_2_vs_1`` renders the CT scan when it is there, else the
#: head phantom; it borrows only VTK's early-termination constant, not VTK).
REQUIRES: dict[str, tuple[Callable[[], str | None], ...]] = {
    "golden_vs_vtk_first": (_needs_vtk, _needs_ct),
    "golden_vs_vtk_rotation": (_needs_vtk, _needs_ct),
    "functional_vs_volpack": (_needs_volpack,),
}
#: The rows ``vtk=False`` (``--no-vtk``) skips: every use of VTK.
VTK_ROWS = ("golden_vs_vtk_first", "golden_vs_vtk_rotation")


def plan(rows: Sequence[str] = ROWS, *, vtk: bool = True) -> list[tuple[str, str | None]]:
    """The rows of ``rows`` in the table's order, each with why it will be skipped
    (``None``: it runs), found before any row is measured."""
    unknown = set(rows) - set(ROWS)
    if unknown:
        raise ValueError(f"unknown rows {sorted(unknown)}; rows are {', '.join(ROWS)}")
    out = []
    for name in (r for r in ROWS if r in rows):
        why = "--no-vtk" if not vtk and name in VTK_ROWS else None
        for check in REQUIRES.get(name, ()) if why is None else ():
            why = check()
            if why is not None:
                break
        out.append((name, why))
    return out


# ----------------------------------------------------------------- the table


def _row(name: str, measure: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """Row ``name`` measured: its value, goal and whether it is met; ``failed`` with the
    error in one line when the measurement raised (the other rows still run)."""
    goal, better, unit, definition = GOALS[name]
    before = list(os.getloadavg())
    start = time.perf_counter()
    try:
        row = measure()
    except Exception as exc:  # a failed row is reported, the table goes on
        row = {"status": "failed", "error": one_line(exc)}
    row.setdefault("status", "ok" if row.get("value") is not None else "not available")
    value = row.get("value")
    met = None
    if value is not None and row["status"] == "ok":
        met = value >= goal if better == "higher" else value <= goal
    return {
        "row": name,
        **row,
        "goal": goal,
        "better": better,
        "unit": unit,
        "definition": definition,
        "goal_met": met,
        "wall_seconds": time.perf_counter() - start,
        "load_average_before": before,
        "load_average_after": list(os.getloadavg()),
    }


def skipped(name: str, why: str) -> dict[str, Any]:
    """The record of row ``name`` skipped because of ``why`` (a missing extra or a flag)."""
    goal, better, unit, definition = GOALS[name]
    return {
        "row": name,
        "status": "skipped",
        "note": why,
        "goal": goal,
        "better": better,
        "unit": unit,
        "definition": definition,
        "goal_met": None,
    }


def run(
    rows: Sequence[str] = ROWS,
    *,
    vtk: bool = True,
    sizes: Sequence[int] = (128, 256),
    memory_size: int = 512,
    repeats: int = 3,
    frames: int = 10,
    log: Callable[[str], None] = lambda m: None,
    on_row: Callable[[str], None] = lambda name: None,
    out: list[dict[str, Any]] | None = None,
) -> list[dict[str, Any]]:
    """The rows named in ``rows`` (in the table's order), as JSON-ready dicts.

    A row whose requirement is missing (:data:`REQUIRES`; ``vtk`` false: every VTK row)
    is ``skipped`` with the reason, before anything is measured; a row that raises is
    ``failed`` with its error (logged) and the others still run.  ``on_row(name)`` is
    called as each measured row starts; ``out``, when given, is filled as rows finish.
    """
    planned = plan(rows, vtk=vtk)
    out = [] if out is None else out
    pair: tuple[dict, dict] | Exception | None = None

    def cycle_pair() -> tuple[dict, dict]:
        """The two cycle rows' shared measurement, made once (a failure too: both rows
        fail with it rather than measuring for minutes again)."""
        nonlocal pair
        if pair is None:
            try:
                pair = cycle_and_timing_only(sizes, repeats)
            except Exception as exc:
                pair = exc
        if isinstance(pair, Exception):
            raise pair
        return pair

    measures: dict[str, Callable[[], dict[str, Any]]] = {
        "golden_vs_vtk_first": lambda: golden_vs_vtk_first(repeats),
        "golden_vs_vtk_rotation": lambda: golden_vs_vtk_rotation(frames),
        # VolPack frames take ~8 ms: more rounds than the other rows against the noise.
        "functional_vs_volpack": lambda: functional_vs_volpack(frames, max(repeats, 5)),
        "functional_vs_golden": lambda: functional_vs_golden(repeats),
        "cycle_samples_per_s": lambda: cycle_pair()[0],
        "timing_only_vs_cycle": lambda: cycle_pair()[1],
        "cycle_512_peak_bytes": lambda: cycle_512_peak(memory_size),
        "threads_2_vs_1": lambda: threads_2_vs_1(repeats),
    }
    out.extend(skipped(name, why) for name, why in planned if why is not None)
    for name, why in planned:
        if why is not None:
            continue
        on_row(name)
        out.append(_row(name, measures[name]))
        if out[-1]["status"] == "failed":
            log(f"{name}: failed: {out[-1]['error']}")
    out.sort(key=lambda r: ROWS.index(r["row"]))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", nargs="+", default=list(ROWS), choices=ROWS)
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--memory-size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--no-vtk", action="store_true", help="skip the VTK rows")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    from hwsim.studies.bench import machine_info

    def say(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    for name, why in plan(args.rows, vtk=not args.no_vtk):
        if why is not None:
            say(f"{name}: skipped: {why}")
    machine = machine_info()  # its load average: the run's start
    rows = run(
        args.rows,
        vtk=not args.no_vtk,
        sizes=args.sizes,
        memory_size=args.memory_size,
        repeats=args.repeats,
        frames=args.frames,
        log=say,
        on_row=lambda name: say(f"speed table: {name}"),
    )
    machine["load_average_after"] = machine_info()["load_average"]
    print(format_rows(rows, (machine["load_average"], machine["load_average_after"])))
    report = {
        "schema": 1,
        "benchmark": "speed-table",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine,
        "rows": rows,
    }
    write_report(report, args.out)
    return 1 if any(r["status"] == "failed" for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
