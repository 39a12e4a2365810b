"""``hwsim figures``: each machine's published figures against hwsim's, at every timing rung.

# Ref: shared/docs/reference/architectures.md (the published numbers, tagged [V]/[R]/[I]);
#      design.md section 6 (a faithful config reproduces the headline figures) and 8.

A machine's figures are the numbers in its arch file's ``[published]`` table.  Each one
is measured on a scenario the key names:

``fps_N``
    frames per second on the dense scenario at ``N^3``: ``1 / frame_seconds``;
``seconds_N``
    seconds per frame on the same scenario;
``samples_per_second``
    simulated samples over simulated frame time on the machine's smallest ``fps_N`` /
    ``seconds_N`` scenario (else ``N = 256``).

The dense scenario is the CT-like head phantom at ``N^3``, composite with Phong shading
(the built-in ``head`` scene's transfer function, light and material), viewed along a
volume axis on an ``N x N`` image whose pixels are one voxel wide (zoom ``sqrt 3``: ray
``i`` passes through voxel centre ``i``).  Every machine order then takes one sample per
voxel, ``N^3`` samples a frame, which is how the papers count a frame.

The voxel width is the machine's widest (``formats.voxel.bits``): "256^3 x 16-bit" for
EM-Cube, 12 bits for VolumePro 500.  The head phantom fills most of its box, and a
machine without early termination or space leaping visits every sample whatever the
content, so this is the dense-volume figure the papers quote; the scenario a machine
with those features is timed on is brute force (the scene enables neither).

Sub-tables of ``[published]``: ``evidence`` (key -> ``fitted``, ``peak`` or
``prediction``, required: :mod:`hwsim.spec.published`), ``fitted_from`` (key -> the keys set
from it), ``tolerance`` (key -> allowed relative difference, e.g. ``fps_256 = 0.05``) and
``notes`` (key -> text shown beside the row); ``[[published.measured]]`` entries are
figures on their own scenarios (:class:`hwsim.spec.published.Scenario`).

Nothing is fitted here: each simulated figure is the rung's own cycle count divided by
the machine's clock.  Whether the comparison is worth anything is the row's ``evidence``:
a ``fitted`` or ``peak`` row shows only the modelled overheads.  Where a machine has two or
more figures, :func:`leave_one_out` fits the clock on each in turn and predicts the others
from the same cycle counts (cycles do not depend on the clock: every timing parameter is in
clocks), so a reader sees what one figure says about the rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from hwsim.core.errors import HwsimError, InputError, NotAvailableError
from hwsim.core.paths import display_text
from hwsim.spec.arch import ArchConfig
from hwsim.spec.published import (
    DEFAULT_SIZE,
    TIME_METRICS,
    PublishedFigure,
    Scenario,
    parse_published,
)
from hwsim.spec.scene import Scene, VolumeSpec, load_scene

__all__ = [
    "TIMING_RUNGS",
    "FigureRow",
    "LeaveOneOut",
    "PublishedFigure",
    "figure_machine",
    "figure_scene",
    "figure_size",
    "figure_value",
    "leave_one_out",
    "measure_figures",
    "published_figures",
]

#: The rungs that produce a cycle count, cheapest first.
TIMING_RUNGS = ("functional", "transaction", "cycle", "rtl")


@dataclass
class FigureRow:
    """One published figure of one machine at one rung."""

    arch: str
    figure: str
    published: float
    size: int
    rung: str
    status: str  # "ok", "not modelled", "skipped", "refused" (by the rung) or "failed"
    simulated: float | None = None
    difference: float | None = None  # simulated / published - 1
    tolerance: float | None = None
    within: bool | None = None
    cycles: int | None = None
    samples: int | None = None
    wall_seconds: float | None = None
    note: str = ""
    #: "single frame", or "frame period" (the cycle or transaction rung's back-to-back
    #: frames, where the machine model times them: the continuous rate the papers quote).
    basis: str = "single frame"
    single_frame: float | None = None  # the one-frame value when basis is the period
    #: "fitted", "peak" or "prediction" (hwsim.spec.published): what the comparison is worth.
    evidence: str = "prediction"
    metric: str = ""  # "fps", "seconds" or "samples_per_second"
    fitted_from: list[str] | None = None  # the arch keys set from this figure
    scenario: str = ""  # what the figure is measured on
    kind: str = "stated"  # "measured", "simulated" or "stated" by its source
    source: str = ""  # the tagged citation of a measured figure
    #: the frame's time apart from its cycles (a supervolume's host read back), for
    #: leave_one_out's refit of the clock
    host_seconds: float = 0.0
    used_cycles: int | None = None  # the cycles the figure was computed from


def figure_size(arch: ArchConfig, key: str) -> int | None:
    """The scenario side ``N`` a published key is measured at (None: not a figure)."""
    for fig in published_figures(arch):
        if fig.key == key:
            return fig.size
    return None


def published_figures(arch: ArchConfig) -> list[PublishedFigure]:
    """The figures of ``arch``'s ``[published]`` table, in file order (checked when the
    file was loaded; an :class:`ArchConfig` built in code is checked here)."""
    return parse_published(
        arch.published, source=arch.source, peak_samples_per_second=arch.peak_samples_per_second
    )


def figure_scene(scenario: int | Scenario) -> Scene:
    """The scene of a figure's scenario; an int ``N`` is the dense scenario on an ``N^3``
    head phantom (one sample per voxel)."""
    import dataclasses

    if isinstance(scenario, int):
        scenario = Scenario((scenario, scenario, scenario))
    size = scenario.volume[0]
    scene = load_scene("head")
    spec = VolumeSpec(phantom="head", params=(("size", size),))
    width, height = scenario.image or (size, size)
    # Pixel pitch 2 r / (zoom W) with r = sqrt(3) N / 2: N / W voxels when zoom = sqrt(3).
    view = dataclasses.replace(
        scene.view,
        azimuth=scenario.view[0],
        elevation=scenario.view[1],
        projection=scenario.projection,
        width=width,
        height=height,
        zoom=math.sqrt(3.0),
    )
    render_spec = dataclasses.replace(
        scene.render,
        mode=scenario.mode,
        supersampling=scenario.supersampling,
        early_termination=scenario.early_termination,
    )
    name = f"dense-head-{size}" if scenario.dense else f"figure-head-{size}"
    return scene.replace(volume=spec, view=view, render=render_spec, name=name)


def figure_value(key: str, run, cycles: int | None = None) -> float:
    """The figure ``key`` of a render: from its frame cycles, or from ``cycles`` (the
    back-to-back frame period) when given; a supervolume's frame adds the host's read
    back of its bricks (``derived.supervolume.host_seconds``)."""
    seconds = (run.cycles if cycles is None else cycles) / run.clock_hz
    seconds += host_seconds(run)
    return _from_seconds(key, seconds, run.samples)


def host_seconds(run) -> float:
    """A frame's time that is not machine cycles: a supervolume's host read back."""
    return float(run.derived.get("supervolume", {}).get("host_seconds", 0.0))


def _metric(key: str) -> str:
    for metric in ("fps", "seconds"):
        if key == metric or key.startswith(metric + "_"):
            return metric
    return "samples_per_second"


def _from_seconds(key: str, seconds: float, samples: int) -> float:
    """A frame time as the figure ``key`` measures it.  The map is its own inverse
    (``1 / x``, ``x``, ``samples / x``), so it also turns a figure back into seconds."""
    metric = _metric(key)
    if metric == "fps":
        return 1.0 / seconds
    if metric == "seconds":
        return seconds
    return samples / seconds


_to_seconds = _from_seconds


def figure_machine(arch: ArchConfig) -> ArchConfig:
    """``arch`` at its widest voxels, as the papers quote the figures ("256^3 x 16-bit")."""
    import dataclasses

    from hwsim.core.config import flatten_table

    formats = {**flatten_table(arch.formats), "voxel.bits": max(arch.value_bits)}
    return dataclasses.replace(arch, formats=formats)


def measure_figures(
    archs: list[ArchConfig],
    rungs: tuple[str, ...] = TIMING_RUNGS,
    *,
    max_size: int = DEFAULT_SIZE,
    progress: Callable[[int, int, str], None] | None = None,
) -> list[FigureRow]:
    """Every numeric published figure of ``archs`` at each of ``rungs``.

    A scenario larger than ``max_size`` (or than the machine addresses) is reported as
    ``skipped`` with the reason; a rung the machine lacks as ``not modelled``.  One
    render per (machine, size, rung) serves all that machine's figures at that size.
    ``progress(done, total, what)`` counts voxels of the planned renders (a render's
    work grows with its voxels), advancing within each render as it reports.
    """
    unknown = [r for r in rungs if r not in TIMING_RUNGS]
    if unknown:
        raise InputError(
            f"unknown timing rung {unknown[0]!r}", key="--rungs", allowed=", ".join(TIMING_RUNGS)
        )
    rows: list[FigureRow] = []
    volumes: dict[int, Any] = {}
    plans = {arch.name: published_figures(arch) for arch in archs}
    total = sum(
        scenario.voxels * len(rungs)
        for arch in archs
        for scenario in dict.fromkeys(f.scenario for f in plans[arch.name])
        if _measurable(arch, max(scenario.volume), max_size)
    )
    done = 0
    for arch in archs:
        machine = figure_machine(arch)
        for rung in rungs:
            runs: dict[Scenario, Any] = {}
            for fig in plans[arch.name]:
                row = _planned_row(arch, rung, fig)
                rows.append(row)
                if not _measurable(arch, fig.size, max_size):
                    row.status = "skipped"
                    why = (
                        f"{fig.size}^3 > --max-size {max_size}"
                        if fig.size > max_size
                        else f"{fig.size}^3 exceeds limits.max_volume"
                    )
                    row.note = "; ".join(filter(None, [why, row.note]))
                    continue
                if fig.scenario not in runs:
                    runs[fig.scenario] = _render_scenario(
                        arch, machine, rung, fig.scenario, volumes, progress, done, total
                    )
                    done += fig.scenario.voxels
                _fill_row(row, fig, runs[fig.scenario])
    return rows


def _measurable(arch: ArchConfig, size: int, max_size: int) -> bool:
    """Whether a ``size``^3 scenario is within ``--max-size`` and what ``arch`` addresses."""
    return size <= max_size and bool(arch.supervolumes or size <= max(arch.max_volume))


def _planned_row(arch: ArchConfig, rung: str, fig: PublishedFigure) -> FigureRow:
    """The row of one published figure at one rung, before it is measured."""
    return FigureRow(
        arch.name,
        fig.key,
        fig.value,
        fig.size,
        rung,
        "ok",
        tolerance=fig.tolerance,
        note=fig.note,
        evidence=fig.evidence,
        metric=fig.metric,
        fitted_from=list(fig.fitted_from),
        scenario=fig.scenario.text(),
        kind=fig.kind,
        source=fig.source,
    )


def _render_scenario(
    arch: ArchConfig,
    machine: Any,
    rung: str,
    scenario: Scenario,
    volumes: dict[int, Any],
    progress: Callable[[int, int, str], None] | None,
    done: int,
    total: int,
) -> Any:
    """One render of ``scenario`` at ``rung``: its result, ``None`` if the rung is not
    modelled, or the ``HwsimError`` it failed with.  ``volumes`` caches each size's
    volume; progress runs from ``done`` to ``done`` plus the scenario's voxels."""
    from hwsim.run.fidelity import render, times_back_to_back
    from hwsim.volumes import load_volume

    size = max(scenario.volume)
    what = f"{arch.name} {rung} {scenario.text()}"
    if progress is not None:
        progress(done, total, what)

    def advance(d: int, t: int, base=done, work=scenario.voxels, what=what):
        if progress is not None and t:
            progress(base + work * min(d, t) // t, total, what)

    scene = figure_scene(scenario)
    if size not in volumes:
        volumes[size] = load_volume(scene.volume, scene.base_dir)
    try:
        run = render(
            scene,
            fidelity=rung,
            arch=machine,
            volume=volumes[size],
            # A supervolume's bricks are timed one frame each.
            steady_state=rung in ("cycle", "transaction")
            and times_back_to_back(arch)
            and size <= max(arch.max_volume),
            # A figure needs the event model's cycles, not its image (the
            # same cycles and counters: tests/models/test_timing_only.py);
            # a supervolume's host blend needs the bricks' images.
            timing_only=rung == "transaction" and size <= max(arch.max_volume),
            progress=advance,
        )
    except NotAvailableError:
        run = None
    except HwsimError as exc:  # InputError: the rung refuses the scenario
        run = exc
    if progress is not None:
        progress(done + scenario.voxels, total, what)
    return run


def _fill_row(row: FigureRow, fig: PublishedFigure, run: Any) -> None:
    """Fill ``row`` from ``run`` (a result, ``None`` or an ``HwsimError``)."""
    if run is None:
        row.status = "not modelled"
        return
    if isinstance(run, HwsimError):
        row.status = "refused" if isinstance(run, InputError) else "failed"
        # The error names the machine's file: recorded relative to the repository.
        row.note = "; ".join(filter(None, [row.note, display_text(str(run))]))
        return
    row.cycles, row.samples = int(run.cycles), int(run.samples)
    row.wall_seconds = round(run.wall_seconds, 3)
    if fig.metric not in TIME_METRICS:
        _counter_figure(row, run, fig.value)
        return
    row.simulated = figure_value(fig.metric, run)
    row.used_cycles = int(run.cycles)
    period = run.counters.get("frame.period_cycles")
    if period:
        row.basis, row.single_frame = "frame period", row.simulated
        row.simulated = figure_value(fig.metric, run, int(period))
        row.used_cycles = int(period)
        extra = f"{row.rung}: back-to-back frame period; one frame alone " + (
            f"{row.single_frame:.4g} ({100 * (row.single_frame / fig.value - 1):+.1f}%)"
        )
        row.note = "; ".join(filter(None, [row.note, extra]))
    row.difference = row.simulated / fig.value - 1.0
    row.host_seconds = host_seconds(run)
    if row.tolerance is not None:
        row.within = bool(abs(row.difference) <= row.tolerance)


@dataclass
class LeaveOneOut:
    """One figure predicted from another of the same machine and rung: the clock fitted
    so that the rung's cycles give ``fitted_on`` exactly, then ``figure`` from its own
    cycles at that clock."""

    arch: str
    rung: str
    fitted_on: str
    fitted_evidence: str
    clock_hz: float  # the clock that reproduces ``fitted_on``
    file_clock_hz: float
    figure: str
    evidence: str
    published: float
    predicted: float
    difference: float  # predicted / published - 1


def leave_one_out(rows: list[FigureRow], clocks: dict[str, float]) -> list[LeaveOneOut]:
    """Fit the clock on each measured figure in turn and predict the machine's others.

    Every timing parameter of a machine is in clocks, so a rung's cycle count does not
    depend on the clock and ``seconds = cycles / f + host seconds``: one figure fixes
    ``f`` and the rest follow with no re-render.  ``clocks`` maps machine -> file clock.
    """
    by: dict[tuple[str, str], list[FigureRow]] = {}
    for r in rows:
        if r.status == "ok" and r.used_cycles:
            by.setdefault((r.arch, r.rung), []).append(r)
    out = []
    for (arch, rung), group in by.items():
        if len(group) < 2:
            continue
        for fit in group:
            machine_seconds = _to_seconds(fit.metric, fit.published, fit.samples or 0)
            machine_seconds -= fit.host_seconds
            if machine_seconds <= 0:
                continue
            clock = fit.used_cycles / machine_seconds
            for other in group:
                if other is fit:
                    continue
                seconds = other.used_cycles / clock + other.host_seconds
                predicted = _from_seconds(other.metric, seconds, other.samples or 0)
                out.append(
                    LeaveOneOut(
                        arch,
                        rung,
                        fit.figure,
                        fit.evidence,
                        clock,
                        clocks.get(arch, float("nan")),
                        other.figure,
                        other.evidence,
                        other.published,
                        predicted,
                        predicted / other.published - 1.0,
                    )
                )
    return out


def _counter_figure(row: FigureRow, run, value: float) -> None:
    """A figure read off the rung's counters (the block cache's hit rate)."""
    lookups = run.counters.get("cache.lookups")
    if not lookups:
        row.status = "not modelled"
        row.note = "; ".join(filter(None, [row.note, f"no block cache at the {row.rung} rung"]))
        return
    row.simulated = run.counters["cache.hits"] / lookups
    row.difference = row.simulated / value - 1.0
    if row.tolerance is not None:
        row.within = bool(abs(row.difference) <= row.tolerance)
