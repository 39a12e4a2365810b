"""The fidelity-ladder trade: every rung of every machine, speed against error.

# Ref: shared/docs/design.md section 3 (the ladder, its contracts and the two kinds of
#      image error); docs/fidelity.md.

For each scene the ideal float64 ray caster (``golden`` without an architecture) is the
reference.  Then for each architecture of :func:`hwsim.run.fidelity.builtin_archs` and each
rung of :data:`hwsim.run.fidelity.FIDELITIES` that :mod:`hwsim.studies.trade.plan` keeps
(the machine has the rung and the scene's features; what-ifs only with ``extend``; the
rest is listed once in ``not_run``, or is a row with its reason when the user named the
machine and the rung):

* ``golden`` at the machine's sample positions gives the **algorithmic** error (its
  image against the ideal ray caster);
* every other rung gives the **numerical** error (its image against golden at the same
  positions), the wall time, simulated samples per wall second, and, when the ``cycle``
  rung ran for that case, the relative cycle-count error against it, with what the two
  sides share for it (``cycle_independence``, :mod:`hwsim.studies.trade.independence`): on the
  Cube-4 family the transaction rung times frames with the cycle rung's own functions, so
  its ``cycle_error`` is a consistency check, not a measurement.

Rows are written as ``trade.csv`` / ``trade.json``, the table with the reasons of its empty
cells as ``trade.md``; ``trade.png`` is the Pareto plot (wall seconds against error, both
log scale, the non-dominated points joined).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.core.paths import output_folder, write_text_atomic
from hwsim.numerics import agreement, max_abs_error, per_channel, psnr, rmse
from hwsim.spec.scene import Scene, ViewSpec, VolumeSpec, load_scene
from hwsim.studies.trade.files import write_rows
from hwsim.studies.trade.ladder_plot import pareto_front, plot_ladder
from hwsim.studies.trade.plan import (
    NOT_AVAILABLE,
    UNSUPPORTED,
    WHAT_IF,
    NotRun,
    TradeRows,
    Verdict,
    cell_verdict,
    scene_verdict,
)
from hwsim.studies.trade.table import ladder_markdown, reason_lines
from hwsim.volumes.volume import Volume

__all__ = [
    "LADDER_SCENES",
    "TradeCase",
    "TradeRows",
    "image_error",
    "ladder_cases",
    "ladder_trade",
    "write_ladder_trade",
    "pareto_front",
]

#: Built-in scenes of the default set: (label, built-in scene, phantom).
LADDER_SCENES = (
    ("marschner-lobb", "marschner-lobb", "marschner-lobb"),
    ("head", "head", "head"),
    ("ball", "ball-xray", "ball"),
)


@dataclass(frozen=True)
class TradeCase:
    """One scene of the trade: a label, the scene and its loaded volume."""

    label: str
    scene: Scene
    volume: Volume


def ladder_cases(volumes: Sequence[str] = (), image: int = 64, size: int = 64) -> list[TradeCase]:
    """The built-in phantoms (Marschner-Lobb, head, ball at ``size^3``) plus each file.

    The phantoms use their built-in scenes (ML iso-surface, head composite + Phong, ball
    X-ray); files use the head scene's view and light with the automatic transfer
    function.  Every image is ``image x image``.
    """
    from hwsim.volumes import make_phantom, read_volume

    cases = []
    for label, scene_name, phantom in LADDER_SCENES:
        scene = load_scene(scene_name)
        scene = scene.replace(
            volume=VolumeSpec(phantom=phantom, params=(("size", size),)),
            view=dataclasses.replace(scene.view, width=image, height=image),
        )
        cases.append(TradeCase(label, scene, make_phantom(phantom, size=size)))
    base = load_scene("head")
    for path in volumes:
        volume = read_volume(path)
        scene = Scene(
            name=volume.name,
            volume=VolumeSpec(path=str(path)),
            view=ViewSpec(azimuth=30, elevation=15, zoom=1.3, width=image, height=image),
            lights=base.lights,
            material=base.material,
        )
        cases.append(TradeCase(volume.name, scene, volume))
    return cases


def image_error(reference: np.ndarray, test: np.ndarray) -> dict[str, Any]:
    """RMSE, PSNR and max abs error of ``test`` against ``reference``, and per channel.

    RGBA images are in 0..1 (PSNR peak 1); scalar images (mip, minip, xray) keep volume
    or world units, so their PSNR peak is the reference's largest magnitude.
    """
    peak = 1.0 if reference.ndim == 3 else float(np.max(np.abs(reference))) or 1.0
    return {
        "rmse": rmse(reference, test),
        "psnr_db": psnr(reference, test, peak),
        "max_abs": max_abs_error(reference, test),
        "match": agreement(reference, test, peak),
        "peak": peak,
        "per_channel": per_channel(reference, test, peak),
    }


def _error_columns(prefix: str, err: dict[str, Any] | None) -> dict[str, Any]:
    keys = ("rmse", "psnr_db", "max_abs", "match")
    return {f"{prefix}_{k}": (err[k] if err else None) for k in keys}


def ladder_trade(
    cases: Sequence[TradeCase],
    archs: Sequence[str] | None = None,
    rungs: Sequence[str] | None = None,
    progress: Callable[[int, int], None] | None = None,
    *,
    extend: bool = False,
) -> TradeRows:
    """Measure every (scene, machine, rung) the machine has; one row each (module doc).

    The product is :mod:`hwsim.studies.trade.plan`'s: the rungs that model each machine
    and the scenes inside its declared features, plus with ``extend`` the what-ifs
    (status ``what-if``, ``extensions`` naming the features).  The cells left out are in
    the result's ``not_run``, each reason once; naming both ``archs`` and ``rungs`` makes
    each of those cells a row instead (``unsupported`` or ``not available``, the reason
    in ``note``)."""
    from hwsim.run.fidelity import FIDELITIES, builtin_archs, render, resolve_arch

    arch_names = list(archs) if archs else list(builtin_archs())
    rung_names = list(rungs) if rungs else list(FIDELITIES)
    for r in rung_names:
        if r not in FIDELITIES:
            raise InputError(f"unknown rung {r!r}", key="--rungs", allowed=", ".join(FIDELITIES))
    if "golden" not in rung_names:
        rung_names.insert(0, "golden")  # the reference of every error column
    named = bool(archs) and bool(rungs)
    machines = {a: resolve_arch(a) for a in arch_names}
    plans = [_case_plan(case, machines, rung_names, extend) for case in cases]
    not_run = NotRun([c.label for c in cases], rung_names)
    rows: list[dict[str, Any]] = []
    total = sum(1 + sum(v.runs for cells in p.values() for v in cells.values()) for p in plans)
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)

    for case, plan in zip(cases, plans, strict=True):
        # Untimed warm-up: fills the golden renderer's per-volume cache (float copy and
        # voxel gradients), which every later render of this volume reuses.
        render(case.scene, fidelity="golden", volume=case.volume)
        ideal = render(case.scene, fidelity="golden", volume=case.volume)
        reference = _row(case, "ideal", ideal, status="ok", note="reference: ideal ray caster")
        reference["total_rmse"], reference["total_match"] = 0.0, "identical"
        rows.append(reference)
        tick()
        for arch, cells in plan.items():
            measured, refused = _arch_rows(case, arch, cells, ideal, tick, extend=extend)
            for rung, verdict in refused.items():
                if named:
                    measured.append(_empty(case, arch, rung, verdict.status, verdict.reason))
                else:
                    not_run.add(case.label, arch, rung, verdict)
            rows.extend(sorted(measured, key=lambda r: rung_names.index(r["rung"])))
    return TradeRows(rows, not_run.entries())


def _case_plan(
    case: TradeCase, machines: dict[str, Any], rung_names: list[str], extend: bool
) -> dict[str, dict[str, Verdict]]:
    """Each machine's verdict on each rung of ``case``, before anything is rendered."""
    plan = {}
    for arch, machine in machines.items():
        scene = scene_verdict(case.scene, case.volume, machine, extend=extend)
        plan[arch] = {rung: cell_verdict(machine, rung, scene) for rung in rung_names}
    return plan


def _arch_rows(
    case: TradeCase,
    arch: str,
    cells: dict[str, Verdict],
    ideal: Any,
    tick: Callable[[], None],
    *,
    extend: bool,
) -> tuple[list[dict[str, Any]], dict[str, Verdict]]:
    """One machine's rows of ``case``: each rung its ``cells`` verdict runs, its render
    measured against ``ideal``, the machine's golden and its cycle rung (or a ``not
    available`` row: a rung this build lacks, a missing simulator); and the verdicts of the
    rungs not measured, planned so or refused when rendered (a rung's own limits)."""
    from hwsim.run.fidelity import render

    runs: dict[str, Any] = {}
    failed: list[dict[str, Any]] = []
    refused = {rung: v for rung, v in cells.items() if not v.runs}
    for rung in (r for r, v in cells.items() if v.runs):
        try:
            runs[rung] = render(
                case.scene, fidelity=rung, arch=arch, volume=case.volume, extend=extend
            )
        except NotAvailableError as exc:  # modelled, but not in this build: a failure
            failed.append(_empty(case, arch, rung, NOT_AVAILABLE, exc.message))
        except InputError as exc:  # refused by the rung's own limits
            refused[rung] = Verdict(UNSUPPORTED, exc.message)
        tick()
    cycle = runs.get("cycle")
    full = None
    if cycle is not None:  # measured elision: the same frame with every unit
        full = render(
            case.scene,
            fidelity="cycle",
            arch=arch,
            volume=case.volume,
            elaborate_all=True,
            extend=extend,
        )
    rows = [_measured_row(case, arch, rung, run, ideal, runs, full) for rung, run in runs.items()]
    return rows + failed, refused


def _measured_row(
    case: TradeCase,
    arch: str,
    rung: str,
    run: Any,
    ideal: Any,
    runs: dict[str, Any],
    full: Any,
) -> dict[str, Any]:
    """The row of one rendered rung: its errors against the ideal ray caster (total), the
    machine's golden (numerical) and golden against ideal (algorithmic); the cycle rung's
    elision against ``full`` (every unit elaborated); its cycles against the cycle rung's."""
    golden, cycle = runs.get("golden"), runs.get("cycle")
    row = _row(case, arch, run, status=WHAT_IF if run.extensions else "ok")
    total = image_error(ideal.image, run.image)
    row["total_rmse"], row["total_match"] = total["rmse"], total["match"]
    if golden is not None:
        row.update(_error_columns("algorithmic", image_error(ideal.image, golden.image)))
        if rung != "golden":
            num = image_error(golden.image, run.image)
            row.update(_error_columns("numerical", num))
            row["numerical_per_channel"] = num["per_channel"]
    if rung == "cycle" and full is not None:
        row["elision_speedup"] = full.wall_seconds / run.wall_seconds
        row["elision_exact"] = bool(
            np.array_equal(full.image, run.image) and full.cycles == run.cycles
        )
    if run.cycles is not None and cycle is not None and cycle.cycles:
        row["cycle_error"] = (run.cycles - cycle.cycles) / cycle.cycles
        row["cycle_reference"] = "cycle"
        row["cycle_independence"] = _cycle_independence(rung, arch)
    elif run.cycles is not None:
        row["cycle_reference"] = "cycle rung not available"
    return row


_COLUMNS = (
    "scene",
    "volume",
    "arch",
    "rung",
    "status",
    "wall_seconds",
    "samples",
    "wall_samples_per_second",
    "cycles",
    "frame_seconds",
    "simulated_samples_per_second",
    "numerical_rmse",
    "numerical_psnr_db",
    "numerical_max_abs",
    "numerical_match",
    "algorithmic_rmse",
    "algorithmic_psnr_db",
    "algorithmic_max_abs",
    "algorithmic_match",
    "total_rmse",
    "total_match",
    "cycle_error",
    "cycle_reference",
    "cycle_independence",
    "elaborated_units",
    "elided_units",
    "elision_saving",
    "elision_speedup",
    "elision_exact",
    "extensions",
    "note",
)


def _cycle_independence(rung: str, arch: str) -> str:
    """What ``rung``'s cycle count shares with the cycle rung's on ``arch``: a verdict with
    the shared code (``shared (cube4_latency, ...)``), or ``reference`` for the cycle rung."""
    from hwsim.run.fidelity import resolve_arch
    from hwsim.studies.trade.independence import cycle_comparison

    comparison = cycle_comparison(rung, resolve_arch(arch))
    return "reference" if comparison is None else comparison.label


def _empty(case: TradeCase, arch: str, rung: str, status: str, note: str = "") -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(_COLUMNS)
    row.update(scene=case.label, volume=case.volume.name, arch=arch, rung=rung, status=status)
    row["note"] = note
    return row


def _row(case: TradeCase, arch: str, run: Any, *, status: str, note: str = "") -> dict[str, Any]:
    """Speed, timing and elision of one render (error columns are added by the caller)."""
    row = _empty(case, arch, "golden" if arch == "ideal" else run.fidelity, status, note)
    frame = run.cycles / run.clock_hz if run.cycles is not None and run.clock_hz else None
    all_units = len(run.elaborated_units) + len(run.elided_units)
    row.update(
        wall_seconds=run.wall_seconds,
        samples=run.samples,
        wall_samples_per_second=run.samples / run.wall_seconds if run.wall_seconds else None,
        cycles=run.cycles,
        frame_seconds=frame,
        simulated_samples_per_second=run.samples / frame if frame else None,
        elaborated_units=list(run.elaborated_units),
        elided_units=list(run.elided_units),
        # Share of the pipeline's per-sample unit evaluations the scene does not need.
        elision_saving=len(run.elided_units) / all_units if all_units else 0.0,
        extensions=[e["feature"] for e in run.extensions],
        note=note,
    )
    if run.extensions and not note:
        row["note"] = "what-if: " + "; ".join(
            f"{e['asked']} (the machine's {e['feature']}: {e['machine']})" for e in run.extensions
        )
    return row


def ladder_paths(out_dir: str | Path) -> dict[str, Path]:
    """The files :func:`write_ladder_trade` writes in ``out_dir``, by kind."""
    return {kind: Path(out_dir) / f"trade.{kind}" for kind in ("csv", "json", "md", "png")}


def write_ladder_trade(rows: list[dict[str, Any]], out_dir: str | Path) -> dict[str, Path]:
    """Write ``trade.csv``, ``trade.json`` (with ``not_run`` when ``rows`` is a
    :class:`TradeRows`), the table with its reasons as ``trade.md`` and the Pareto plot
    ``trade.png``."""
    output_folder(out_dir)
    paths = ladder_paths(out_dir)
    not_run = list(getattr(rows, "not_run", []))
    flat = [{k: v for k, v in r.items() if k != "numerical_per_channel"} for r in rows]
    write_rows(flat, paths["csv"], None)
    write_rows(list(rows), None, paths["json"], not_run=not_run)
    write_text_atomic(paths["md"], ladder_markdown(rows, not_run))
    plot_ladder(rows, paths["png"], reason_lines(rows, not_run))
    return paths
