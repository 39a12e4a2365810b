"""``hwsim figures``' files and tables: figures.json, figures.csv and figures.md, the
human table with each row's evidence, the leave-one-out table, and the command itself.

# Ref: docs/figures.md (what each column and label means).
"""

from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import platform
from dataclasses import asdict
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError
from hwsim.studies.figures import TIMING_RUNGS, FigureRow, leave_one_out, measure_figures

__all__ = [
    "EVIDENCE_LEGEND",
    "figures_command",
    "loo_table",
    "markdown_tables",
    "table",
    "write_figures",
]


def machine_facts() -> dict[str, Any]:
    """Where and when the figures were measured."""
    from hwsim import __version__

    return {
        "hwsim": __version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "measured": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }


#: What each evidence label means, printed under every figures table.
EVIDENCE_LEGEND = (
    "evidence: 'fitted' = a machine parameter was set from this figure (fitted_from names "
    "it), so the row shows only the modelled overheads; 'peak' = the figure is pipelines x "
    "clock restated, so the row measures only what the model loses below one sample per "
    "pipeline per clock; 'prediction' = no parameter came from it. Only prediction rows "
    "are errors; none of the rows is a validation of the timing."
)


def figures_paths(out_dir: str | Path) -> dict[str, Path]:
    """The files :func:`write_figures` writes in ``out_dir``, by kind."""
    return {kind: Path(out_dir) / f"figures.{kind}" for kind in ("json", "csv", "md")}


def write_figures(
    rows: list[FigureRow], out_dir: str | Path, clocks: dict[str, float] | None = None
) -> dict[str, Path]:
    """``figures.json``, ``figures.csv`` and ``figures.md`` in ``out_dir``; ``clocks``
    (machine -> file clock) adds the leave-one-out table."""
    from hwsim.core.paths import atomic_write, output_folder, write_text_atomic

    out = output_folder(out_dir)
    loo = leave_one_out(rows, clocks or {})
    data = {
        "schema": 2,
        "machine": machine_facts(),
        "evidence": EVIDENCE_LEGEND,
        "rows": [asdict(r) for r in rows],
        "leave_one_out": [asdict(r) for r in loo],
    }
    paths = figures_paths(out)
    write_text_atomic(paths["json"], json.dumps(data, indent=2) + "\n")
    with atomic_write(paths["csv"]) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])) if rows else ["arch"])
        writer.writeheader()
        for r in rows:
            d = asdict(r)
            d["fitted_from"] = " ".join(d["fitted_from"] or [])
            writer.writerow(d)
    write_text_atomic(paths["md"], markdown_tables(data))
    return paths


def markdown_tables(data: dict[str, Any]) -> str:
    """The figures table, its legend and the leave-one-out table as Markdown."""
    header, body = table(data["rows"])
    lines = ["# Published figures", "", *_md(header, body), "", data.get("evidence", "")]
    loo = data.get("leave_one_out") or []
    if loo:
        lh, lb = loo_table(loo)
        lines += ["", "## Leave one out: the clock fitted on one figure, the others predicted"]
        lines += ["", *_md(lh, lb)]
    return "\n".join(lines) + "\n"


def _md(header: list[str], body: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(r) + " |" for r in body]


def loo_table(loo: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    header = ["machine", "rung", "fitted on", "clock fitted", "file clock", "predicted"]
    header += ["published", "predicted value", "error"]
    body = [
        [
            d["arch"],
            d["rung"],
            f"{d['fitted_on']} ({d['fitted_evidence']})",
            f"{d['clock_hz'] / 1e6:.4g} MHz",
            f"{d['file_clock_hz'] / 1e6:.4g} MHz",
            f"{d['figure']} ({d['evidence']})",
            _num(d["published"]),
            _num(d["predicted"]),
            f"{100 * d['difference']:+.1f}%",
        ]
        for d in loo
    ]
    return header, body


def _num(v: float | None) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    return f"{v:.4g}"


def table(rows: list[dict[str, Any]] | list[FigureRow]) -> tuple[list[str], list[list[str]]]:
    """The human table: one line per machine and figure, one column per rung."""
    dicts = [asdict(r) if isinstance(r, FigureRow) else r for r in rows]
    rungs = [r for r in TIMING_RUNGS if any(d["rung"] == r for d in dicts)]
    header = ["machine", "figure", "evidence", "published", "scenario"]
    for rung in rungs:
        header += [rung, "diff"]
    header += ["tolerance", "note"]
    grouped: dict[tuple[str, str], dict[str, dict[str, Any]]] = {}
    for d in dicts:
        grouped.setdefault((d["arch"], d["figure"]), {})[d["rung"]] = d
    body = []
    for (arch, figure), by_rung in grouped.items():
        first = next(iter(by_rung.values()))
        evidence = first.get("evidence", "?")
        if first.get("fitted_from"):
            evidence += " (" + ", ".join(first["fitted_from"]) + ")"
        scenario = first.get("scenario") or f"dense head {first['size']}^3"
        line = [arch, figure, evidence, _num(first["published"]), scenario]
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
        if first.get("source"):
            notes.append(f"{first.get('kind', 'stated')}: {first['source']}")
        line += ["-" if tol is None else f"±{100 * tol:g}%", "; ".join(notes)]
        body.append(line)
    return header, body


def figures_command(args, progress_bar: Any) -> int:
    """``hwsim figures``: measure, write the three files, print the table."""
    from hwsim.core.paths import in_folder, plan_outputs
    from hwsim.run.fidelity import builtin_archs, resolve_arch

    if args.max_size < 1:
        raise InputError(f"invalid {args.max_size}", key="--max-size", allowed=">= 1")
    if args.arch:  # loaded first: each file they read is an input of the plan below
        archs = [resolve_arch(a) for a in args.arch]
    else:
        archs = [a for a in builtin_archs().values() if a.published]
    outputs = in_folder("--out", args.out, figures_paths(args.out).values())
    plan_outputs([("--arch", a) for a in args.arch], outputs)
    rungs = tuple(r.strip() for r in args.rungs.split(",")) if args.rungs else TIMING_RUNGS
    with progress_bar(args.quiet, "figures", unit="voxel") as progress:
        rows = measure_figures(archs, rungs, max_size=args.max_size, progress=progress)
    paths = write_figures(rows, args.out, {a.name: a.clock_hz for a in archs})
    if not args.quiet:
        print(paths["md"].read_text())
        print(f"wrote {paths['json']}, {paths['csv'].name}, {paths['md'].name}")
    return 0
