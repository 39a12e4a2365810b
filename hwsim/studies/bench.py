"""``hwsim bench``: the speed of every rung and the goal ratios, measured in one run.

# Ref: shared/docs/design.md section 3 (expected speed per rung) and conventions item 11
#      (speed lives in benchmarks, as JSON, against a reference run in the same process).

Every rung renders the same scene (head phantom, ``ct`` preset, composite + Phong) on
the same machine, median of ``repeats`` renders after a warm-up; the cycle and
transaction rungs run on ``cube4`` when the chosen machine is not modelled at that rung
(said in a note). The rtl rung renders at most 128^3 on the Cube-4 top, so it and
``cycle_vs_rtl`` are measured on their own scene (:data:`RTL_SCENE`: head 64^3, lit
composite, ``cube4``; the first run builds the Verilator model, minutes), the cycle rung
rendering the same scene beside it; without a simulator, ``cycle_vs_rtl`` falls back to
the cycle rung's simulated cycles per second over the Verilator model's measured clocks
per second (docs/rtl.md), saying so.

Then the speed table of issue 18, from ``benchmarks/speed_table.py`` (imported, not
copied; its docstring defines every row): golden against VTK (first frame and a
rotation), the functional rung against VolPack and against golden, the cycle rung's
samples per second and the timing-only transaction rung's speed-up on every machine,
the peak memory of a 512^3 cycle frame, and two threads against one.  ``rows`` picks
rows; each says whether its goal is met.  Whatever needs more than the run install (the
rtl rung: the ``rtl`` extra; the VTK rows: ``bench``; VolPack: apt) is checked before
anything is measured and, when missing, ``skipped`` with a one-line reason naming what
to install; whatever raises is ``failed`` with its error and the rest still runs.
Three ratios are measured here:

==============================  ==========================================  =====
ratio                           definition                                  goal
==============================  ==========================================  =====
``cycle_vs_rtl``                rtl seconds / cycle seconds (RTL_SCENE)     10
``sweep_2_vs_1_workers``        1-worker / 2-worker seconds, 24-run sweep   1.8
``split_frame_2_vs_1_workers``  1-worker / 2-worker seconds, one cube4      1.7
                                cycle frame (256^3, benchmarks/split_frame)
==============================  ==========================================  =====
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.engine.metrics import issued_samples

__all__ = [
    "GOALS",
    "TABLE_GOALS",
    "RTL_SCENE",
    "machine_info",
    "rung_speeds",
    "rtl_speeds",
    "rtl_missing",
    "run_bench",
    "format_bench",
    "failures",
    "one_line",
    "status_text",
]

#: Goal of each ratio (``None``: no number was set).
GOALS = {
    "cycle_vs_rtl": 10.0,
    "sweep_2_vs_1_workers": 1.8,
    "split_frame_2_vs_1_workers": 1.7,
}
#: The speed table's rows (``benchmarks/speed_table.py`` measures them), in order:
#: name -> (goal, "higher" or "lower" is better, unit, definition).
TABLE_GOALS: dict[str, tuple[float, str, str, str]] = {
    "golden_vs_vtk_first": (0.5, "higher", "x", "VTK first-frame s / golden first-frame s"),
    "golden_vs_vtk_rotation": (0.1, "higher", "x", "VTK s/frame / golden s/frame, rotation"),
    "functional_vs_volpack": (0.1, "higher", "x", "VolPack s/frame / functional s/frame"),
    "functional_vs_golden": (2.0, "higher", "x", "golden s / functional s, same positions"),
    "cycle_samples_per_s": (5e6, "higher", "samples/s", "slowest machine, cycle rung"),
    "timing_only_vs_cycle": (10.0, "higher", "x", "smallest cycle s / timing-only s"),
    "cycle_512_peak_bytes": (1.5e9, "lower", "bytes", "largest peak RSS, 512^3 cycle frame"),
    "threads_2_vs_1": (1.7, "higher", "x", "smallest 1-thread s / 2-thread s"),
}
_REPO = Path(__file__).resolve().parents[2]
#: A machine a rung models when the benchmark's machine is not modelled at that rung.
_FALLBACK_ARCH = {"cycle": "cube4", "transaction": "cube4"}
#: The lit P = 4 top's Verilator model over a 64^3 frame (docs/rtl.md, measured by
#: benchmarks/bench_rtl.py): the reference when no simulator is installed to measure it.
RTL_MEASURED_CLOCKS_PER_SECOND = 190e3
#: The rtl rung's benchmark scene: lit composite, so every pipeline computes gradients,
#: Phong shading and compositing.
RTL_SCENE = {"size": 64, "image": 64, "arch": "cube4", "view": (30, 20), "mode": "composite"}


def machine_info() -> dict[str, Any]:
    """CPU model, cores (total and usable), load average, Python and NumPy versions."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "cpu_model": cpu,
        "cores": os.cpu_count(),
        "usable_cores": usable,
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
    }


def _harness(name: str):
    """A module of the repository's ``benchmarks/`` folder, or ``None`` outside a clone."""
    if not (_REPO / "benchmarks" / f"{name}.py").is_file():
        return None
    if str(_REPO) not in sys.path:
        sys.path.insert(0, str(_REPO))
    import importlib

    return importlib.import_module(f"benchmarks.{name}")


def one_line(exc: BaseException) -> str:
    """An exception as one line: its type and the first line of its message."""
    text = (str(exc).strip().splitlines() or [""])[0]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def status_text(entry: dict[str, Any]) -> str:
    """``skipped: why``, ``failed: error`` or the bare status of a rung, row or ratio."""
    why = entry.get("error") or entry.get("note")
    return f"{entry['status']}: {why}" if entry["status"] != "ok" and why else entry["status"]


def failures(report: dict[str, Any]) -> list[str]:
    """The rungs, rows and ratios of a bench report that failed (skipped ones did not)."""
    entries = [
        *report.get("rungs", {}).items(),
        *((r["row"], r) for r in report.get("table", [])),
        *report.get("ratios", {}).items(),
    ]
    return [name for name, e in entries if e.get("status") == "failed"]


def rtl_missing(simulator: str = "verilator") -> str | None:
    """None when the rtl rung can run here, else why not in one line (the ``rtl`` extra
    brings Verilator)."""
    from hwsim.core.errors import NotAvailableError
    from rtl.rung import require_simulator

    try:
        require_simulator(simulator)
    except NotAvailableError as exc:
        return exc.message
    return None


def _failed(exc: Exception, **extra: Any) -> dict[str, Any]:
    return {**extra, "status": "failed", "error": one_line(exc)}


def rung_speeds(
    size: int,
    image: int,
    arch: str,
    repeats: int,
    rtl_size: int = RTL_SCENE["size"],
    *,
    step: Callable[[str], None] = lambda what: None,
    out: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Wall seconds and samples per wall second of every rung on one scene.

    ``step(what)`` is called as each rung starts; ``out``, when given, is filled as the
    rungs finish.  A rung that raises is ``failed`` with its error; the others still run.
    """
    from hwsim.core.errors import NotAvailableError
    from hwsim.run.fidelity import FIDELITIES, render
    from hwsim.spec.scene import Scene, TransferSpec, ViewSpec, VolumeSpec
    from hwsim.volumes import make_phantom

    volume = make_phantom("head", size=size)
    scene = Scene(
        name=f"bench-head-{size}",
        volume=VolumeSpec(phantom="head", params=(("size", size),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=image, height=image, zoom=1.3),
    )

    def timed(rung: str, rung_arch: str) -> dict[str, Any]:
        runs = [render(scene, fidelity=rung, arch=rung_arch, volume=volume) for _ in range(repeats)]
        entry = _timed(runs)
        if rung == "transaction":  # the event model's share, measured inside the render
            for part in ("timing", "image"):
                key = f"transaction.{part}_seconds"
                entry[f"{part}_seconds"] = statistics.median(r.counters[key] for r in runs)
        return entry

    def measure(rung: str) -> dict[str, Any]:
        if rung == "rtl":  # its own small scene; the cycle rung's row on it rides along
            small = rtl_speeds(repeats, size=rtl_size)
            if small["rtl"]["status"] != "ok":
                return small["rtl"]
            return {**small["rtl"], "cycle_same_scene": small["cycle"]}
        rung_arch, note = arch, None
        try:
            render(scene, fidelity=rung, arch=rung_arch, volume=volume)  # warm-up (caches)
        except NotAvailableError as exc:
            if rung not in _FALLBACK_ARCH:
                return {"status": "not available", "note": exc.message}
            rung_arch = _FALLBACK_ARCH[rung]
            note = f"{exc.message}; measured on {rung_arch} instead"
            render(scene, fidelity=rung, arch=rung_arch, volume=volume)
        return {**timed(rung, rung_arch), **({"note": note} if note else {})}

    out = {} if out is None else out
    for rung in FIDELITIES:
        step(f"{rung} rung")
        try:
            out[rung] = measure(rung)
        except Exception as exc:  # a failed rung is reported, the bench goes on
            out[rung] = _failed(exc)
    txn, cyc = out.get("transaction", {}), out.get("cycle", {})
    if txn.get("status") == "ok" and cyc.get("status") == "ok" and txn["arch"] != cyc["arch"]:
        # transaction_vs_cycle compares one machine: time the transaction rung again on
        # the machine the cycle rung ran on.
        try:
            render(scene, fidelity="transaction", arch=cyc["arch"], volume=volume)
            txn["paired_with_cycle"] = timed("transaction", cyc["arch"])
        except Exception as exc:
            txn["paired_with_cycle"] = _failed(exc)
    return out


def _timed(runs) -> dict[str, Any]:
    seconds = statistics.median(r.wall_seconds for r in runs)
    last = runs[-1]
    issued = issued_samples(last.counters or {}, last.samples)
    return {
        "status": "ok",
        "arch": last.arch,
        "sampling": last.sampling,
        "samples": last.samples,
        "issued_samples": issued,
        "seconds": seconds,
        "seconds_all": [r.wall_seconds for r in runs],
        "samples_per_second": issued / seconds,
        "cycles": last.cycles,
        "simulated_cycles_per_second": last.cycles / seconds if last.cycles else None,
    }


def rtl_speeds(
    repeats: int, simulator: str = "verilator", size: int = RTL_SCENE["size"]
) -> dict[str, Any]:
    """The rtl and cycle rungs on :data:`RTL_SCENE` at ``size``^3 (same scene, same frame).

    Returns ``{"rtl": ..., "cycle": ...}`` rows; the rtl row is ``skipped`` (with the
    reason, the ``rtl`` extra) when the simulator is missing, and the cycle rung is not
    run then.  The rtl wall time is a whole frame as the
    user sees it: simulator start, host loads, frame, pixel read-back (the Verilator build
    is cached and made by the warm-up render).  Both on one thread: the Verilator model
    runs on one.
    """

    from hwsim.core.errors import NotAvailableError
    from hwsim.core.threads import using
    from hwsim.run.fidelity import render
    from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
    from hwsim.volumes import make_phantom

    cfg = {**RTL_SCENE, "size": size, "image": size}
    volume = make_phantom("head", size=cfg["size"])
    az, el = cfg["view"]
    scene = Scene(
        name=f"bench-rtl-head-{cfg['size']}",
        volume=VolumeSpec(phantom="head", params=(("size", cfg["size"]),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=cfg["image"], height=cfg["image"]),
        render=RenderSpec(mode=cfg["mode"]),
    )
    note = (
        f"head {cfg['size']}^3 lit {cfg['mode']} on {cfg['arch']} (the RTL top's scene "
        "size), cycle rung on the same scene"
    )
    missing = rtl_missing(simulator)
    if missing is not None:
        return {"rtl": {"status": "skipped", "note": missing}, "cycle": None}
    out: dict[str, Any] = {}
    for rung in ("cycle", "rtl"):
        kw = {"simulator": simulator} if rung == "rtl" else {}
        with using(1):
            try:
                render(scene, fidelity=rung, arch=cfg["arch"], volume=volume, **kw)  # warm-up
            except NotAvailableError as exc:
                out[rung] = {"status": "not available", "note": exc.message}
                continue
            runs = [
                render(scene, fidelity=rung, arch=cfg["arch"], volume=volume, **kw)
                for _ in range(repeats)
            ]
        out[rung] = {**_timed(runs), "note": note}
    return out


def _ratio(name: str, value: float | None, definition: str, **extra: Any) -> dict[str, Any]:
    goal = GOALS[name]
    return {
        "status": "ok" if value is not None else "not available",
        "value": value,
        "definition": definition,
        "goal": goal,
        "goal_met": (value >= goal) if value is not None and goal is not None else None,
        **extra,
    }


def _from_rungs(rungs: dict[str, Any], name: str, slow: str, fast: str) -> dict[str, Any]:
    definition = f"{slow} seconds / {fast} seconds"
    missing = [r for r in (slow, fast) if rungs[r]["status"] != "ok"]
    if missing:
        return _ratio(name, None, definition, missing=missing)
    return _ratio(name, rungs[slow]["seconds"] / rungs[fast]["seconds"], definition)


def run_bench(
    size: int = 64,
    image: int = 128,
    arch: str = "volumepro500",
    repeats: int = 3,
    *,
    vtk: bool = True,
    sweep: bool = True,
    sweep_size: int = 96,
    split_size: int = 256,
    rows: Sequence[str] | None = None,
    rtl_size: int = RTL_SCENE["size"],
    table_sizes: Sequence[int] = (128, 256),
    memory_size: int = 512,
    log: Callable[[str], None] = lambda m: None,
    progress: Callable[[int, int, str | None], None] = lambda done, total, what: None,
    checkpoint: Callable[[dict[str, Any]], None] = lambda report: None,
) -> dict[str, Any]:
    """Measure every rung, the speed table's rows (``rows``: names of
    ``benchmarks/speed_table.py``'s rows, all by default; ``()`` none) and the three
    ratios of their own (``cycle_vs_rtl``, ``sweep_2_vs_1_workers``,
    ``split_frame_2_vs_1_workers``); the JSON-ready report.

    What needs an extra the install lacks (the rtl rung: ``rtl``; the VTK rows:
    ``bench``; VolPack: apt) is found first, logged as ``name: skipped: why`` and recorded
    ``skipped``; ``vtk`` false skips every VTK row.  Anything that raises is ``failed``
    with its error and the rest still runs (:func:`failures` lists them).
    ``progress(done, total, what)`` follows the steps (rungs, rows, ratios);
    ``checkpoint(report)`` receives the report so far as each step starts and at the end
    (``complete`` true), so a partial report can be saved.
    """
    from hwsim.run.fidelity import FIDELITIES

    report: dict[str, Any] = {
        "schema": 3,
        "benchmark": "hwsim-bench",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "complete": False,
        "machine": machine_info(),
        "scene": {"phantom": "head", "size": size, "image": image, "arch": arch},
        "rungs": {},
        "table": [],
    }
    table = _harness("speed_table")
    planned = [] if table is None else table.plan(_table_rows(table, rows), vtk=vtk)
    for name, why in [("rtl rung", rtl_missing()), *planned]:
        if why is not None:
            log(f"{name}: skipped: {why}")
    total = len(FIDELITIES) + sum(why is None for _, why in planned) + (2 if sweep else 0)
    step = _Steps(total, progress, checkpoint, report)
    rung_speeds(size, image, arch, repeats, rtl_size, step=step, out=report["rungs"])
    if table is None:
        report["table_note"] = "benchmarks/ folder not found (run from a clone)"
    else:
        table.run(
            _table_rows(table, rows),
            vtk=vtk,
            sizes=table_sizes,
            memory_size=memory_size,
            repeats=repeats,
            log=log,
            on_row=step,
            out=report["table"],
        )
    ratios = report["ratios"] = {}
    ratios["cycle_vs_rtl"] = _guarded("cycle_vs_rtl", _cycle_vs_rtl, report["rungs"])
    ratios["sweep_2_vs_1_workers"] = _guarded(
        "sweep_2_vs_1_workers", _sweep_ratio, sweep, sweep_size, step
    )
    ratios["split_frame_2_vs_1_workers"] = _guarded(
        "split_frame_2_vs_1_workers", _split_frame_ratio, sweep, split_size, step
    )
    report["machine"]["load_average_after"] = machine_info()["load_average"]
    report["complete"] = True
    step.finish()
    return report


class _Steps:
    """The bench's steps: ``step(what)`` as each starts moves the progress on and hands
    the report so far to ``checkpoint``."""

    def __init__(self, total: int, progress, checkpoint, report: dict[str, Any]) -> None:
        self.total, self.done = total, 0
        self.progress, self.checkpoint, self.report = progress, checkpoint, report

    def __call__(self, what: str) -> None:
        self.checkpoint(self.report)
        self.progress(self.done, self.total, what)
        self.done += 1

    def finish(self) -> None:
        self.checkpoint(self.report)
        self.progress(self.total, self.total, None)


def _guarded(name: str, measure: Callable[..., dict[str, Any]], *args: Any) -> dict[str, Any]:
    """Ratio ``name`` from ``measure(*args)``, or ``failed`` with the error it raised."""
    try:
        return measure(*args)
    except Exception as exc:  # a failed ratio is reported, the bench goes on
        return _failed(exc, **_ratio(name, None, ""))


def _table_rows(table, rows: Sequence[str] | None) -> list[str]:
    return list(table.ROWS if rows is None else rows)


def _cycle_vs_rtl(rungs: dict[str, Any]) -> dict[str, Any]:
    """The cycle rung's speed against the rtl rung's: measured on the same frame when the
    rtl rung ran, else against the Verilator model's recorded clocks per second."""
    if rungs["rtl"]["status"] == "ok":
        rtl, cyc = rungs["rtl"], rungs["rtl"]["cycle_same_scene"]
        return _ratio(
            "cycle_vs_rtl",
            rtl["seconds"] / cyc["seconds"],
            "rtl seconds / cycle seconds, same frame (" + rtl["note"] + ")",
            rtl_seconds=rtl["seconds"],
            cycle_seconds=cyc["seconds"],
            rtl_samples_per_second=rtl["samples_per_second"],
            cycle_samples_per_second=cyc["samples_per_second"],
            rtl_simulated_cycles_per_second=rtl["simulated_cycles_per_second"],
            same_cycles=rtl["cycles"] == cyc["cycles"],
        )
    if rungs["cycle"]["status"] == "ok":
        return _ratio(
            "cycle_vs_rtl",
            rungs["cycle"]["simulated_cycles_per_second"] / RTL_MEASURED_CLOCKS_PER_SECOND,
            "cycle-rung simulated cycles/s / the Verilator model's 190 k clocks/s "
            "(docs/rtl.md; no HDL simulator here to run the rtl rung)",
        )
    return _from_rungs(rungs, "cycle_vs_rtl", "rtl", "cycle")


def _sweep_ratio(sweep: bool, sweep_size: int, step: Callable[[str], None]) -> dict[str, Any]:
    """A 24-run sweep on 1 and 2 Dask workers (``benchmarks/bench_sweep.py``)."""
    if not sweep:
        return {**_ratio("sweep_2_vs_1_workers", None, "", note="--no-sweep"), "status": "skipped"}
    step(f"sweep_2_vs_1_workers (24 runs at {sweep_size}^3)")
    scaling = _harness("bench_sweep")
    if scaling is None:
        return _ratio("sweep_2_vs_1_workers", None, "", note="benchmarks/ folder not found")
    sweep_report = scaling.run(sweep_size, (1, 2), repeats=2)
    return _ratio(
        "sweep_2_vs_1_workers",
        sweep_report["speedup_2_workers"],
        "1-worker seconds / 2-worker seconds, 24-run sweep",
        cases=sweep_report["cases"],
    )


def _split_frame_ratio(sweep: bool, split_size: int, step: Callable[[str], None]) -> dict[str, Any]:
    """One cube4 cycle frame split across 1 and 2 Dask workers
    (``benchmarks/split_frame.py``)."""
    name = "split_frame_2_vs_1_workers"
    if not sweep:
        return {**_ratio(name, None, "", note="--no-sweep"), "status": "skipped"}
    step(f"{name} (a cube4 cycle frame, {split_size}^3)")
    split = _harness("split_frame")
    if split is None:
        return _ratio(name, None, "", note="benchmarks/ folder not found")
    split_report = split.run((split_size,), (1, 2), reference_max=0, log=lambda line: None)
    return _ratio(
        "split_frame_2_vs_1_workers",
        split_report["speedup_2_vs_1"].get(f"{split_size}^3 warm"),
        "1-worker s / 2-worker s, one cube4 cycle frame of the dense scenario on a "
        "running local cluster (second frame)",
        rows=split_report["rows"],
        identical=all(c["identical"] for c in split_report["checks"]),
    )


def _load(load: Sequence[float] | None) -> str:
    """The 1, 5 and 15-minute load averages as ``uptime`` prints them."""
    if load is None:
        return "load average: unknown"
    return "load average: " + ", ".join(f"{x:.2f}" for x in load)


def format_bench(report: dict[str, Any]) -> str:
    """Rung speeds, the speed table and the ratios as text; what was skipped or failed
    says why."""
    m = report["machine"]
    lines = [
        f"{m['cpu_model']}, {m['usable_cores']} usable cores, {_load(m['load_average'])}",
        f"{'rung':<13}{'seconds':>9}{'Msamples/s':>12}  status",
    ]
    for rung, r in report["rungs"].items():
        if r["status"] == "ok":
            lines.append(
                f"{rung:<13}{r['seconds']:>9.3f}{r['samples_per_second'] / 1e6:>12.2f}  ok"
            )
        else:
            lines.append(f"{rung:<13}{'-':>9}{'-':>12}  {status_text(r)}")
    table = _harness("speed_table")
    if report.get("table") and table is not None:
        lines.append(table.format_rows(report["table"]))
    if m.get("load_average_after") is not None:
        lines.append(f"at the end: {_load(m['load_average_after'])}")
    lines.append(f"{'ratio':<22}{'value':>8}{'goal':>7}  met")
    for name, r in report.get("ratios", {}).items():
        value = "-" if r["value"] is None else f"{r['value']:.3g}"
        goal = "-" if r["goal"] is None else f"{r['goal']:g}"
        met = {True: "yes", False: "no", None: status_text(r)}[r["goal_met"]]
        lines.append(f"{name:<22}{value:>8}{goal:>7}  {met}")
    return "\n".join(lines)
