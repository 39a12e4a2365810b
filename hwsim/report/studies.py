"""The report's blocks for studies: a fidelity-ladder trade table, a sweep database and
the published-figures table (``hwsim report`` given their folders; docs/cli.md)."""

from __future__ import annotations

from pathlib import Path

from hwsim.core.paths import atomic_write
from hwsim.report import plots
from hwsim.report.document import Block
from hwsim.report.inputs import read_figures, read_sweep_rows, read_trade
from hwsim.report.tables import (
    NOT_RECORDED,
    figure_units,
    fmt_value,
    footnoted,
    loo_units,
    merged_diffs,
)
from hwsim.studies.trade.files import EXACT_LEGEND, psnr_cell

__all__ = ["SHIPPED_FIGURES", "figures_blocks", "sweep_blocks", "trade_blocks"]


def trade_blocks(folder: Path, out: Path, index: int) -> list[Block]:
    rows = read_trade(folder / "trade.json")["rows"]
    blocks: list[Block] = [("h2", f"Fidelity-ladder trade ({folder})")]
    header = [
        "scene",
        "arch",
        "rung",
        "status",
        "wall s",
        "Msamples/s wall",
        "cycles",
        "numerical PSNR dB",
        "algorithmic PSNR dB",
        "cycle error",
    ]
    table = []
    for r in rows:
        sps = r["wall_samples_per_second"]
        table.append(
            [
                r["scene"],
                r["arch"],
                r["rung"],
                r["status"],
                fmt_value(r["wall_seconds"], ".3f") if r["wall_seconds"] is not None else "-",
                f"{sps / 1e6:.2f}" if sps else "-",
                fmt_value(r["cycles"]) if r["cycles"] is not None else "-",
                psnr_cell(r, "numerical"),
                psnr_cell(r, "algorithmic"),
                f"{r['cycle_error']:.2%}"
                if r.get("cycle_error") is not None
                else (r.get("cycle_reference") or "-"),
            ]
        )
    blocks.append(
        (
            "p",
            "Numerical: the rung against golden at the same sample positions. "
            "Algorithmic: golden at the machine's positions against the ideal ray caster. "
            "Cycle error: against the cycle rung of the same case. " + EXACT_LEGEND + ".",
        )
    )
    blocks.append(("table", header, table))
    png = folder / "trade.png"
    if png.is_file():
        copy = plots.plot_path(out, "trade", index)
        with atomic_write(copy) as tmp:
            tmp.write_bytes(png.read_bytes())
        blocks.append(("img", copy, "speed against error, Pareto front dashed"))
    return blocks


def sweep_blocks(path: Path) -> list[Block]:
    """One row per run of a sweep database (``hwsim sweep --db``), sorted by the runs'
    parameters (:func:`hwsim.studies.sweep.db.by_parameters`); a run whose wall time
    includes its worker's JIT compile is marked."""
    rows = read_sweep_rows(path)
    failed = sum(r["status"] != "ok" for r in rows)
    table = [
        [
            r["label"] or "",
            r["status"],
            fmt_value(r["cycles"]) if r["cycles"] is not None else "-",
            fmt_value(1.0 / r["frame_seconds"]) if r["frame_seconds"] else "-",
            fmt_value(r["samples_per_second"]) if r["samples_per_second"] else "-",
            fmt_value(r["wall_seconds"], ".3f") if r["wall_seconds"] is not None else "-",
            {1: "yes [1]", 0: "no"}.get(r.get("includes_compile"), NOT_RECORDED),
            r["error"] or "",
        ]
        for r in rows
    ]
    header = ["run", "status", "cycles", "simulated fps", "simulated samples/s", "wall s"]
    header += ["includes compile", "error"]
    note = (
        "Rows sorted by their parameters (names alphabetically, values ascending). [1] The "
        "first run of its worker process: its wall time includes the imports and numba's "
        "JIT compile (or cache load), so it is not comparable with the warm runs' wall times."
    )
    return [
        ("h2", f"Sweep ({path})"),
        ("p", f"{len(rows)} run(s), {failed} failed."),
        ("table", header, table),
        ("p", note),
    ]


#: The table measured for the repository (benchmarks/results), shown when no
#: ``hwsim figures`` folder is among the inputs.
SHIPPED_FIGURES = (
    Path(__file__).resolve().parents[2] / "benchmarks/results/published-figures/figures.json"
)


def figures_blocks(path: Path, out: Path) -> list[Block]:
    from hwsim.core.paths import display_path
    from hwsim.studies.figures_tables import EVIDENCE_LEGEND, loo_table, table

    data = read_figures(path)
    m = data.get("machine") or {}
    shown = display_path(path, out)  # never this machine's absolute path
    header, body = merged_diffs(*figure_units(*table(data["rows"]), data["rows"]))
    header, body, notes = footnoted(header, body, "note")
    blocks: list[Block] = [
        ("h2", "Published figures of every machine"),
        (
            "p",
            f"Each machine's published figure against hwsim's at every timing rung, on its "
            f"scenario (docs/figures.md); from {shown}, measured {m.get('measured', '?')} "
            f"with hwsim {m.get('hwsim', '?')}. Each rung's value is followed by its diff, "
            "simulated / published - 1; "
            "'OUT' marks a row beyond its acceptance band; notes [n] are listed under the "
            "table.",
        ),
        ("table", header, body),
        ("notes", notes),
        ("p", data.get("evidence") or EVIDENCE_LEGEND),
    ]
    if data.get("leave_one_out"):
        lh, lb = loo_units(*loo_table(data["leave_one_out"]), data["leave_one_out"])
        blocks += [
            ("h3", "Leave one out: the clock fitted on one figure, the others predicted"),
            ("table", lh, lb),
        ]
    return blocks
