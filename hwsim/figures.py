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

Optional sub-tables of ``[published]``: ``tolerance`` (key -> allowed relative
difference, e.g. ``fps_256 = 0.05``) and ``notes`` (key -> text shown beside the row).
Nothing here is fitted: each simulated figure is the rung's own cycle count divided by
the machine's clock.
"""

from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import platform
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from hwsim.arch import ArchConfig
from hwsim.errors import HwsimError, InputError, NotAvailableError
from hwsim.scene import Scene, VolumeSpec, load_scene

__all__ = [
    "TIMING_RUNGS",
    "FigureRow",
    "PublishedFigure",
    "figure_machine",
    "figure_scene",
    "figure_size",
    "figure_value",
    "measure_figures",
    "published_figures",
    "write_figures",
]

#: The rungs that produce a cycle count, cheapest first.
TIMING_RUNGS = ("functional", "transaction", "cycle", "rtl")
#: Scenario side used for ``samples_per_second`` when the file names no size.
DEFAULT_SIZE = 256


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


def figure_size(arch: ArchConfig, key: str) -> int | None:
    """The scenario side ``N`` a published key is measured at (None: not a figure)."""
    for prefix in ("fps_", "seconds_"):
        if key.startswith(prefix) and key[len(prefix) :].isdigit():
            return int(key[len(prefix) :])
    if key == "samples_per_second":
        sizes = [figure_size(arch, k) for k in arch.published if k != key]
        sizes = [s for s in sizes if s is not None]
        return min(sizes) if sizes else DEFAULT_SIZE
    return None


@dataclass(frozen=True)
class PublishedFigure:
    """One row of a machine's ``[published]`` table: the only place a figure is written."""

    key: str
    value: float
    size: int  # the scenario side it is quoted at (:func:`figure_size`)
    tolerance: float | None  # the acceptance band, where the file sets one
    note: str


def published_figures(arch: ArchConfig) -> list[PublishedFigure]:
    """The numeric figures of ``arch``'s ``[published]`` table, in file order."""
    published = arch.published
    tolerance = published.get("tolerance", {}) or {}
    notes = published.get("notes", {}) or {}
    out = []
    for key, value in published.items():
        size = figure_size(arch, key)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and size is not None:
            out.append(
                PublishedFigure(
                    key, float(value), size, tolerance.get(key), str(notes.get(key, ""))
                )
            )
    return out


def figure_scene(size: int) -> Scene:
    """The dense scenario on a ``size^3`` head phantom (one sample per voxel)."""
    import dataclasses

    scene = load_scene("head")
    spec = VolumeSpec(phantom="head", params=(("size", size),))
    # Pixel pitch 2 r / (zoom N) with r = sqrt(3) N / 2: one voxel when zoom = sqrt(3).
    view = dataclasses.replace(
        scene.view, azimuth=0.0, elevation=0.0, width=size, height=size, zoom=math.sqrt(3.0)
    )
    return scene.replace(volume=spec, view=view, name=f"dense-head-{size}")


def figure_value(key: str, run, cycles: int | None = None) -> float:
    """The figure ``key`` of a render: from its frame cycles, or from ``cycles`` (the
    back-to-back frame period) when given; a supervolume's frame adds the host's read
    back of its bricks (``derived.supervolume.host_seconds``)."""
    seconds = (run.cycles if cycles is None else cycles) / run.clock_hz
    seconds += run.derived.get("supervolume", {}).get("host_seconds", 0.0)
    if key.startswith("fps_"):
        return 1.0 / seconds
    if key.startswith("seconds_"):
        return seconds
    return run.samples / seconds


def figure_machine(arch: ArchConfig) -> ArchConfig:
    """``arch`` at its widest voxels, as the papers quote the figures ("256^3 x 16-bit")."""
    import dataclasses

    from hwsim.config import flatten_table

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
    from hwsim.fidelity import render, times_back_to_back
    from hwsim.volumes import load_volume

    unknown = [r for r in rungs if r not in TIMING_RUNGS]
    if unknown:
        raise InputError(
            f"unknown timing rung {unknown[0]!r}", key="--rungs", allowed=", ".join(TIMING_RUNGS)
        )
    rows: list[FigureRow] = []
    volumes: dict[int, Any] = {}
    plans = {arch.name: published_figures(arch) for arch in archs}
    total = sum(
        size**3 * len(rungs)
        for arch in archs
        for size in set(f.size for f in plans[arch.name])
        if size <= max_size and (arch.supervolumes or size <= max(arch.max_volume))
    )
    done = 0
    for arch in archs:
        machine = figure_machine(arch)
        for rung in rungs:
            runs: dict[int, Any] = {}
            for fig in plans[arch.name]:
                key, value, size = fig.key, fig.value, fig.size
                row = FigureRow(
                    arch.name, key, value, size, rung, "ok", tolerance=fig.tolerance, note=fig.note
                )
                rows.append(row)
                if size > max_size or (size > max(arch.max_volume) and not arch.supervolumes):
                    row.status = "skipped"
                    why = (
                        f"{size}^3 > --max-size {max_size}"
                        if size > max_size
                        else f"{size}^3 exceeds limits.max_volume"
                    )
                    row.note = "; ".join(filter(None, [why, row.note]))
                    continue
                if size not in runs:
                    what = f"{arch.name} {rung} {size}^3"
                    if progress is not None:
                        progress(done, total, what)

                    def advance(d: int, t: int, base=done, work=size**3, what=what) -> None:
                        if progress is not None and t:
                            progress(base + work * min(d, t) // t, total, what)

                    scene = figure_scene(size)
                    if size not in volumes:
                        volumes[size] = load_volume(scene.volume, scene.base_dir)
                    try:
                        runs[size] = render(
                            scene,
                            fidelity=rung,
                            arch=machine,
                            volume=volumes[size],
                            # A supervolume's bricks are timed one frame each.
                            steady_state=rung in ("cycle", "transaction")
                            and times_back_to_back(arch)
                            and size <= max(arch.max_volume),
                            progress=advance,
                        )
                    except NotAvailableError:
                        runs[size] = None
                    except HwsimError as exc:  # InputError: the rung refuses the scenario
                        runs[size] = exc
                    done += size**3
                    if progress is not None:
                        progress(done, total, what)
                run = runs[size]
                if run is None:
                    row.status = "not modelled"
                    continue
                if isinstance(run, HwsimError):
                    row.status = "refused" if isinstance(run, InputError) else "failed"
                    row.note = "; ".join(filter(None, [row.note, str(run)]))
                    continue
                row.simulated = figure_value(key, run)
                period = run.counters.get("frame.period_cycles")
                if period:
                    row.basis, row.single_frame = "frame period", row.simulated
                    row.simulated = figure_value(key, run, int(period))
                    extra = f"{rung}: back-to-back frame period; one frame alone " + (
                        f"{row.single_frame:.4g} ({100 * (row.single_frame / value - 1):+.1f}%)"
                    )
                    row.note = "; ".join(filter(None, [row.note, extra]))
                row.difference = row.simulated / value - 1.0
                row.cycles, row.samples = int(run.cycles), int(run.samples)
                row.wall_seconds = round(run.wall_seconds, 3)
                if row.tolerance is not None:
                    row.within = bool(abs(row.difference) <= row.tolerance)
    return rows


def machine_facts() -> dict[str, Any]:
    """Where and when the figures were measured."""
    from hwsim import __version__

    return {
        "hwsim": __version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "measured": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }


def write_figures(rows: list[FigureRow], out_dir: str | Path) -> dict[str, Path]:
    """``figures.json``, ``figures.csv`` and ``figures.md`` in ``out_dir``."""
    from hwsim.paths import output_folder

    out = output_folder(out_dir)
    data = {"schema": 1, "machine": machine_facts(), "rows": [asdict(r) for r in rows]}
    paths = {"json": out / "figures.json", "csv": out / "figures.csv", "md": out / "figures.md"}
    paths["json"].write_text(json.dumps(data, indent=2) + "\n")
    with paths["csv"].open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])) if rows else ["arch"])
        writer.writeheader()
        writer.writerows(asdict(r) for r in rows)
    header, body = table(rows)
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in body]
    paths["md"].write_text("# Published figures\n\n" + "\n".join(lines) + "\n")
    return paths


def _num(v: float | None) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    return f"{v:.4g}"


def table(rows: list[dict[str, Any]] | list[FigureRow]) -> tuple[list[str], list[list[str]]]:
    """The human table: one line per machine and figure, one column per rung."""
    dicts = [asdict(r) if isinstance(r, FigureRow) else r for r in rows]
    rungs = [r for r in TIMING_RUNGS if any(d["rung"] == r for d in dicts)]
    header = ["machine", "figure", "published", "scenario"]
    for rung in rungs:
        header += [rung, "diff"]
    header += ["tolerance", "note"]
    grouped: dict[tuple[str, str], dict[str, dict[str, Any]]] = {}
    for d in dicts:
        grouped.setdefault((d["arch"], d["figure"]), {})[d["rung"]] = d
    body = []
    for (arch, figure), by_rung in grouped.items():
        first = next(iter(by_rung.values()))
        line = [arch, figure, _num(first["published"]), f"dense head {first['size']}^3"]
        for rung in rungs:
            d = by_rung.get(rung)
            if d is None or d["status"] != "ok":
                line += [d["status"] if d else "-", ""]
                continue
            mark = {True: " ok", False: " OUT", None: ""}[d["within"]]
            line += [_num(d["simulated"]), f"{100 * d['difference']:+.1f}%{mark}"]
        tol = first["tolerance"]
        parts = (part for d in by_rung.values() for part in d["note"].split("; ") if part)
        notes = list(dict.fromkeys(parts))
        line += ["-" if tol is None else f"±{100 * tol:g}%", "; ".join(notes)]
        body.append(line)
    return header, body


def figures_command(args, progress_bar: Any) -> int:
    """``hwsim figures``: measure, write the three files, print the table."""
    from hwsim.fidelity import builtin_archs, resolve_arch
    from hwsim.paths import output_folder

    if args.max_size < 1:
        raise InputError(f"invalid {args.max_size}", key="--max-size", allowed=">= 1")
    output_folder(args.out)
    if args.arch:
        archs = [resolve_arch(a) for a in args.arch]
    else:
        archs = [a for a in builtin_archs().values() if a.published]
    rungs = tuple(r.strip() for r in args.rungs.split(",")) if args.rungs else TIMING_RUNGS
    with progress_bar(args.quiet, "figures", unit="voxel") as progress:
        rows = measure_figures(archs, rungs, max_size=args.max_size, progress=progress)
    paths = write_figures(rows, args.out)
    if not args.quiet:
        print(paths["md"].read_text())
        print(f"wrote {paths['json']}, {paths['csv'].name}, {paths['md'].name}")
    return 0
