"""``hwsim report RUN_DIR... --out DIR``: a report a person reads without the terminal.

# Ref: shared/docs/design.md section 8 (report.md / report.html with plots, compared
#      against the published figures of the real machines).

Inputs are folders ``hwsim render`` (or ``hwsim sweep --out``) wrote (``stats.json``,
``image.npy``) and folders ``hwsim trade`` wrote (``trade.json``).  For each run the
report shows golden, simulated and a difference heat map; golden is a golden run among
the inputs with the same scene and sample positions, else it is rendered here.  Unit
utilisation, stalls and memory bandwidth come from the run's raw counters; a rung that
does not record them is reported as "not recorded", never estimated.

Both files are built from one list of blocks, so they say the same thing:
``report.md`` links the PNGs beside it, ``report.html`` embeds them (base64) and is
self-contained.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.errors import HwsimError, InputError
from hwsim.core.paths import write_text_atomic
from hwsim.report import plots
from hwsim.report.document import Block, html_page, markdown
from hwsim.report.energy import energy_blocks
from hwsim.report.inputs import (
    read_image,
    read_stats,
    read_sweep_facts,
)
from hwsim.report.studies import SHIPPED_FIGURES, figures_blocks, sweep_blocks, trade_blocks
from hwsim.report.tables import METRIC_UNITS, NOT_RECORDED, fmt_value

__all__ = ["RunRecord", "load_run", "build_report", "write_report"]


@dataclass
class RunRecord:
    """One run folder: its stats, image and the sweep's architecture overrides (if any)."""

    folder: Path
    stats: dict[str, Any]
    image: np.ndarray
    overrides: dict[str, Any]

    @property
    def title(self) -> str:
        s = self.stats
        where = s["arch"] or "ideal rays"
        return (
            f"{s['scene'].get('name', 'scene')} / {s['volume']['name']}: {s['fidelity']} on {where}"
        )


def load_run(folder: str | Path) -> RunRecord:
    """Read ``stats.json`` and ``image.npy`` of a render folder, each checked against
    its declared shape (:mod:`hwsim.report.inputs`)."""
    folder = Path(folder)
    for name in ("stats.json", "image.npy"):
        if not (folder / name).exists():
            raise InputError(f"not a run folder: {name} missing", source=str(folder), key="RUN_DIR")
    stats = read_stats(folder / "stats.json")
    try:  # the recorded scene must parse: the report renders golden from it
        _scene_from_stats(stats, folder)
    except InputError as exc:
        key = f"scene.{exc.key}" if exc.key else "scene"
        raise InputError(
            exc.message, source=str(folder / "stats.json"), key=key, allowed=exc.allowed
        ) from None
    image = read_image(folder / "image.npy")
    facts = folder / "sweep.json"  # written beside a sweep's run (hwsim sweep --out)
    overrides = read_sweep_facts(facts) if facts.is_file() else {}
    return RunRecord(folder, stats, image, overrides)


# --------------------------------------------------------------------------- blocks


def _scene_from_stats(stats: dict[str, Any], folder: Path | None = None):
    """The run's scene; its recorded paths (relative: hwsim.core.paths.display_path) found
    again beside the scene file, in the run ``folder``, the repository or here."""
    from hwsim.core.paths import locate
    from hwsim.spec.scene import parse_scene

    def clean(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items() if x is not None}
        if isinstance(v, list):
            return [clean(x) for x in v]
        return v

    data = {k: v for k, v in clean(stats["scene"]).items() if k not in ("name", "source")}
    source = stats["scene"].get("source", "<stats.json>")
    if source.endswith(".toml"):
        source = str(locate(source, folder))
    volume = data.get("volume", {})
    if volume.get("path"):
        beside = Path(source).parent if source.endswith(".toml") else None
        volume["path"] = str(locate(volume["path"], beside, folder))
    return parse_scene(data, source=source, name=stats["scene"].get("name", "scene"))


def _golden_for(run: RunRecord, runs: list[RunRecord]) -> tuple[np.ndarray | None, str]:
    """The reference image and where it came from.

    A timed rung is compared with golden at its own sample positions (numerical error);
    golden at a machine's positions with the ideal ray caster (algorithmic error).
    """
    if run.stats["fidelity"] == "golden":
        from hwsim.run.fidelity import render

        try:
            ideal = render(_scene_from_stats(run.stats, run.folder), fidelity="golden")
        except HwsimError as exc:
            return None, f"ideal reference unavailable: {exc}"
        return ideal.image, "the ideal ray caster, rendered by the report (algorithmic error)"
    for other in runs:
        s = other.stats
        if (
            s["fidelity"] == "golden"
            and s["scene"] == run.stats["scene"]
            and s["sampling"] == run.stats["sampling"]
            and other is not run
        ):
            return other.image, f"golden run {other.folder.name}"
    try:
        from hwsim.run.fidelity import render

        scene = _scene_from_stats(run.stats, run.folder)
        arch = run.stats["arch"]
        golden = render(
            scene, fidelity="golden", arch=arch, sampling="ray" if arch else run.stats["sampling"]
        )
        return golden.image, "golden rendered by the report at the same sample positions"
    except HwsimError as exc:
        return None, f"golden reference unavailable: {exc}"


def _published(run: RunRecord) -> list[list[str]]:
    from hwsim.run.fidelity import builtin_archs
    from hwsim.studies.figures import published_figures

    s = run.stats
    arch = builtin_archs().get(s["arch"] or "")
    if arch is None or not arch.published:
        return []
    fps = _fps(s)
    sps = s.get("samples_per_second")
    rows = []
    for fig in published_figures(arch):
        evidence = fig.evidence + (f" ({', '.join(fig.fitted_from)})" if fig.fitted_from else "")
        if fig.metric == "samples_per_second":
            sim, how = sps, "this run's samples / simulated frame time"
        elif fig.metric == "fps" and fig.scenario.dense:
            n = fig.size
            sim = sps / n**3 if sps else None
            how = (
                f"this run's simulated samples/s over {n}^3 (one sample per voxel); "
                f"this volume itself: {fmt_value(fps)} fps"
            )
        else:
            sim, how = None, f"on its own scenario ({fig.scenario.text()}): hwsim figures"
        ratio = fmt_value(sim / fig.value if sim else None, ".3f")
        unit = METRIC_UNITS[fig.metric]
        rows.append(
            [
                fig.key,
                unit,
                evidence,
                fmt_value(fig.value),
                fmt_value(sim) if sim else "-",
                ratio,
                how,
            ]
        )
    return rows


def _run_blocks(run: RunRecord, runs: list[RunRecord], out: Path, index: int) -> list[Block]:
    s = run.stats
    blocks: list[Block] = [("h2", f"Run {index}: {run.title}"), _summary_table(run)]
    blocks += _split_blocks(s)
    blocks += _image_blocks(run, runs, out, index)
    blocks += _unit_blocks(s, out, index)
    blocks += _bandwidth_blocks(s, out, index)
    blocks += energy_blocks(s, out, index, NOT_RECORDED)
    blocks += _published_blocks(run)
    return blocks


def _fps(s: dict[str, Any]) -> float | None:
    """The frame rate ``stats.json`` states (``frames_per_second``: with a supervolume's
    host read back), or for a run written before it, its ``frame_seconds`` inverted."""
    if "frames_per_second" in s:
        return s["frames_per_second"]
    return 1.0 / s["frame_seconds"] if s.get("frame_seconds") else None


def _summary_table(run: RunRecord) -> Block:
    """The run's quantities at a glance: what was rendered, how, and how fast; every
    number with its unit (in the quantity's name)."""
    s = run.stats
    clock = s.get("clock_hz")
    host = []
    if s.get("host_seconds"):  # a supervolume: the machine's part and the host's
        host = [
            ["machine frame time, bricks' cycles (s)", fmt_value(s.get("machine_frame_seconds"))],
            ["host read back of the bricks (s)", fmt_value(s["host_seconds"])],
        ]
    return (
        "table",
        ["quantity", "value"],
        [
            ["folder", str(run.folder)],
            [
                "volume",
                f"{s['volume']['name']} {'x'.join(map(str, s['volume']['shape_zyx']))} "
                f"{s['volume']['dtype']}",
            ],
            ["mode", s["scene"]["render"]["mode"]],
            ["fidelity / sampling", f"{s['fidelity']} / {s['sampling']}"],
            ["architecture", s["arch"] or "none (ideal ray caster)"],
            ["samples (count)", fmt_value(s["samples"])],
            [
                "cycles (count)",
                fmt_value(s.get("cycles"))
                if s["fidelity"] != "golden"
                else "none: golden has no timing",
            ],
            ["clock (MHz)", fmt_value(clock / 1e6 if clock else None)],
            ["simulated frame time (s)", fmt_value(s.get("frame_seconds"))],
            *host,
            ["simulated frame rate (fps)", fmt_value(_fps(s))],
            ["simulated sample rate (samples/s)", fmt_value(s.get("samples_per_second"))],
            ["wall time (s)", fmt_value(s.get("wall_seconds"))],
            ["elaborated units", ", ".join(s.get("elaborated_units", [])) or "-"],
            ["elided units", ", ".join(s.get("elided_units", [])) or "none"],
            [
                "architecture overrides (sweep)",
                ", ".join(f"{k} = {v}" for k, v in run.overrides.items()) or "none",
            ],
        ],
    )


def _image_blocks(run: RunRecord, runs: list[RunRecord], out: Path, index: int) -> list[Block]:
    """The image beside its golden reference and their difference, with the error."""
    s = run.stats
    if s["fidelity"] == "golden" and not s["arch"]:
        reference, origin = None, "this run is the ideal golden reference"
    else:
        reference, origin = _golden_for(run, runs)
    titles = (
        ("ideal golden", f"golden on {s['arch']}")
        if s["fidelity"] == "golden"
        else ("golden, same positions", f"{s['fidelity']} on {s['arch']}")
    )
    png = plots.plot_images(run.image, reference, plots.plot_path(out, "images", index), titles)
    blocks: list[Block] = [
        ("h3", "Images"),
        ("p", f"Reference: {origin}."),
        ("img", png, f"golden, {s['fidelity']} and difference"),
    ]
    if reference is not None and reference.shape == run.image.shape:
        from hwsim.studies.trade.ladder import image_error

        err = image_error(reference, run.image)
        blocks.append(
            (
                "p",
                f"Against the reference: RMSE {fmt_value(err['rmse'])}, "
                f"PSNR {fmt_value(err['psnr_db'], '.2f')} dB, "
                f"max abs error {fmt_value(err['max_abs'])} (peak {err['peak']:g}).",
            )
        )
    return blocks


def _unit_blocks(s: dict[str, Any], out: Path, index: int) -> list[Block]:
    """Per-unit utilisation and stall plots, or why there are none."""
    units = plots.unit_counters(s.get("counters", {}))
    blocks: list[Block] = [("h3", "Unit utilisation and stalls")]
    util = plots.plot_utilisation(
        units, s.get("cycles") or 0, plots.plot_path(out, "utilisation", index)
    )
    stalls = plots.plot_stalls(units, plots.plot_path(out, "stalls", index))
    if util is None and stalls is None:
        blocks.append(
            ("p", f"Per-unit busy and stall counters: {NOT_RECORDED} by the {s['fidelity']} rung.")
        )
    for path, alt in ((util, "utilisation"), (stalls, "stalls")):
        if path is not None:
            blocks.append(("img", path, alt))
    return blocks


def _bandwidth_blocks(s: dict[str, Any], out: Path, index: int) -> list[Block]:
    """The memory bandwidth plot, or why there is none."""
    blocks: list[Block] = [("h3", "Memory bandwidth")]
    memory = plots.memory_counters(s.get("counters", {}))
    bw = plots.plot_bandwidth(
        memory, s.get("frame_seconds") or 0.0, plots.plot_path(out, "bandwidth", index)
    )
    if bw is None:
        blocks.append(
            ("p", f"Memory traffic counters: {NOT_RECORDED} by the {s['fidelity']} rung.")
        )
    else:
        blocks.append(("img", bw, "memory bandwidth"))
    return blocks


def _published_blocks(run: RunRecord) -> list[Block]:
    """The machine's published figures against this run's simulated ones."""
    s = run.stats
    published = _published(run)
    blocks: list[Block] = [("h3", "Published figures")]
    if run.overrides:
        changed = ", ".join(f"{k} = {v}" for k, v in run.overrides.items())
        blocks.append(
            (
                "p",
                f"This run changes the machine ({changed}); the published "
                "figures are for the machine as built.",
            )
        )
    if s.get("frame_seconds") is None:
        blocks.append(("p", f"The {s['fidelity']} rung has no timing: nothing to compare."))
    elif published:
        blocks.append(
            (
                "table",
                ["figure", "unit", "evidence", "published", "simulated", "simulated / published"]
                + ["how"],
                published,
            )
        )
    else:
        blocks.append(
            ("p", "No published figures for this run (no architecture, or none in its file).")
        )
    return blocks


def _split_blocks(s: dict[str, Any]) -> list[Block]:
    """A frame split across workers (``stats.json`` ``split``): each band's share."""
    split = s.get("split")
    if not split:
        return []
    gib = 2.0**30
    rows = [
        [
            str(b["band"]),
            fmt_value(b["rays"]),
            fmt_value(b["samples"]),
            fmt_value(b["rows"]),
            fmt_value(b["seconds"], ".3g"),
            f"{b['peak_rss_bytes'] / gib:.2f}",
            b["host"],
        ]
        for b in split["bands"]
    ]
    text = (
        f"The frame ran in {len(rows)} bands of rays on {split['workers']} Dask workers, each "
        "reading only its rows of the volume; the image, cycles and counters are the "
        "one-process frame's. The driver (combine, pixel bus, image) peaked at "
        f"{split['driver_peak_rss_bytes'] / gib:.2f} GiB."
    )
    head = ["band", "rays", "samples", "beams read (all slices)", "seconds", "peak GiB", "host:pid"]
    return [("h3", "Split across workers"), ("p", text), ("table", head, rows)]


def build_report(folders: list[str | Path], out: Path) -> list[Block]:
    """The report's blocks; plots are written into ``out`` as they are made."""
    run_folders, trades, sweeps, figures = _classify(folders)
    runs = [load_run(folder) for folder in run_folders]
    blocks: list[Block] = [("h1", "hwsim report")]
    from hwsim import __version__

    blocks.append(
        (
            "p",
            f"hwsim {__version__}; {len(runs)} run(s), {len(trades)} trade table(s), "
            f"{len(sweeps)} sweep database(s).",
        )
    )
    if runs:
        blocks.append(
            (
                "table",
                ["run", "scene", "volume", "arch", "fidelity", "cycles", "simulated fps", "wall s"],
                [
                    [
                        str(i),
                        r.stats["scene"].get("name", ""),
                        r.stats["volume"]["name"],
                        r.stats["arch"] or "ideal",
                        r.stats["fidelity"],
                        fmt_value(r.stats.get("cycles")),
                        fmt_value(_fps(r.stats)),
                        fmt_value(r.stats["wall_seconds"], ".3f"),
                    ]
                    for i, r in enumerate(runs, start=1)
                ],
            )
        )
    for i, run in enumerate(runs, start=1):
        blocks += _run_blocks(run, runs, out, i)
    for index, folder in enumerate(trades):
        blocks += trade_blocks(folder, out, index)
    for db in sweeps:
        blocks += sweep_blocks(db)
    if not figures and SHIPPED_FIGURES.is_file():
        figures.append(SHIPPED_FIGURES)
    for path in figures:
        blocks += figures_blocks(path, out)
    if not figures:
        blocks += [
            ("h2", "Published figures of every machine"),
            ("p", "No figures table: run `hwsim figures --out DIR` and give DIR here."),
        ]
    return blocks


def _classify(folders: Iterable[str | Path]) -> tuple[list[Path], ...]:
    """``folders`` as (run folders, trade folders, sweep databases, figures.json files)."""
    runs, trades, sweeps, figures = [], [], [], []
    for f in folders:
        folder = Path(f)
        if folder.is_file():  # a sweep database (refused if it is not one)
            sweeps.append(folder)
        elif (folder / "trade.json").is_file():
            trades.append(folder)
        elif (folder / "figures.json").is_file():
            figures.append(folder / "figures.json")
        else:
            runs.append(folder)
    return runs, trades, sweeps, figures


def report_paths(out_dir: str | Path, folders: Iterable[str | Path] = ()) -> dict[str, Path]:
    """The files :func:`write_report` writes in ``out_dir``: ``report.md``,
    ``report.html`` and, given the report's ``folders``, every plot it may draw for them
    (:func:`hwsim.report.plots.plot_path`), so each is planned before any is drawn."""
    out = Path(out_dir)
    paths = {kind: out / f"report.{kind}" for kind in ("md", "html")}
    runs, trades, _, _ = _classify(folders)
    for index in range(1, len(runs) + 1):
        for kind in plots.RUN_PLOTS:
            paths[f"run{index}-{kind}"] = plots.plot_path(out, kind, index)
    for index in range(len(trades)):
        paths[f"trade-{index}"] = plots.plot_path(out, "trade", index)
    return paths


#: The files a report reads in each run, trade or figures folder it is given.
READS = ("stats.json", "image.npy", "trade.json", "trade.png", "figures.json", "sweep.json")


def report_inputs(runs: list[str | Path]) -> list[tuple[str, Path]]:
    """The files a report of ``runs`` reads (a sweep database itself, else each of
    :data:`READS` in the folder), as :func:`hwsim.core.paths.plan_outputs` takes them."""
    found = []
    for run in map(Path, runs):
        names = READS if run.is_dir() else ("",)
        found += [("RUN_DIR", run / name if name else run) for name in names]
    return found


def write_report(folders: list[str | Path], out_dir: str | Path) -> dict[str, Path]:
    """Write ``report.md``, ``report.html`` and the PNG plots into ``out_dir``."""
    from hwsim.core.paths import output_folder

    if not folders:
        raise InputError("give at least one run folder", key="RUN_DIR")
    out = output_folder(out_dir).resolve()
    blocks = build_report(folders, out)
    paths = report_paths(out)
    write_text_atomic(paths["md"], markdown(blocks, out) + "\n")
    write_text_atomic(paths["html"], html_page(blocks, "hwsim report") + "\n")
    return paths
