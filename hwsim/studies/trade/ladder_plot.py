"""The fidelity ladder's Pareto plot (``trade.png``): one panel per scene, wall seconds
against error, one colour per rung and one marker per machine (hollow: a what-if); under
the legend, the reasons of the cells without a point."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hwsim.core.paths import atomic_write
from hwsim.numerics import EXACT_MATCHES

__all__ = ["pareto_front", "plot_ladder"]


def pareto_front(points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """The non-dominated points (lower seconds and lower error are better), by seconds."""
    front: list[tuple[float, float]] = []
    for x, y in sorted(points):
        if not front or y < front[-1][1]:
            front.append((x, y))
    return front


#: Measured row statuses (a what-if is measured, outside the machine's features).
MEASURED = ("ok", "what-if")

#: Reason lines shown under the legend; the rest are counted (all are in trade.md).
MAX_REASON_LINES = 12


def plot_ladder(rows: list[dict[str, Any]], path: Path, reasons: Sequence[str] = ()) -> None:
    """Write the Pareto plot of the trade ``rows`` to ``path``, ``reasons`` (the table's
    footnotes and not-run lines) under its legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    rungs = list(dict.fromkeys(r["rung"] for r in rows))
    archs = list(dict.fromkeys(r["arch"] for r in rows))
    markers = dict(zip(archs, "o^sDvP*Xh<>", strict=False))
    colours = {r: plt.cm.tab10(i) for i, r in enumerate(rungs)}
    ncols = min(len(scenes), 3)
    nrows = -(-len(scenes) // ncols)
    notes = _fitted(reasons)
    foot = 0.8 + 0.13 * len(notes)  # inches under the panels: legend, then the reasons
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.4 * ncols, 3.6 * nrows + foot), squeeze=False)
    for ax in axes.flat[len(scenes) :]:
        ax.set_visible(False)
    for ax, scene in zip(axes.flat, scenes, strict=False):
        measured = [r for r in rows if r["scene"] == scene and r["status"] in MEASURED]
        _plot_scene(ax, scene, measured, colours, markers)
    handles = [
        plt.Line2D([], [], color=c, marker="o", ls="", label=f"rung {r}")
        for r, c in colours.items()
        if any(x["rung"] == r and x["status"] in MEASURED for x in rows)
    ] + [plt.Line2D([], [], color="k", marker=m, ls="", label=a) for a, m in markers.items()]
    if any(r["status"] == "what-if" for r in rows):
        handles.append(plt.Line2D([], [], color="k", marker="o", mfc="none", ls="",
                                  label="hollow: what-if (--extend)"))  # fmt: skip
    height = 3.6 * nrows + foot
    fig.legend(
        handles=handles,
        loc="lower center",
        bbox_to_anchor=(0.5, (foot - 0.8) / height),
        ncol=min(len(handles), 6),
        fontsize=7,
    )
    for i, line in enumerate(notes):
        fig.text(0.01, (foot - 0.8 - 0.13 * (i + 1)) / height, line, fontsize=6, va="bottom")
    fig.tight_layout(rect=(0, foot / height, 1, 1))
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def _fitted(reasons: Sequence[str]) -> list[str]:
    """The reason lines the plot shows: each cut to one line, at most
    :data:`MAX_REASON_LINES`, the rest counted."""
    lines = [r if len(r) <= 160 else r[:157] + "..." for r in reasons]
    if len(lines) > MAX_REASON_LINES:
        more = len(lines) - MAX_REASON_LINES + 1
        lines = [*lines[: MAX_REASON_LINES - 1], f"... {more} more lines in trade.md"]
    return lines


def _plot_scene(
    ax: Any,
    scene: str,
    measured: list[dict[str, Any]],
    colours: dict[str, Any],
    markers: dict[str, str],
) -> None:
    """One scene's panel: its measured rows and their Pareto front; an exact match is
    drawn on a floor a decade below the smallest error."""
    pts = []
    errors = [r["total_rmse"] for r in measured if r["total_match"] == "differs"]
    floor = min(errors) / 10 if errors else 1e-6
    for r in measured:
        err = r["total_rmse"]
        if err is None:
            continue
        if r["total_match"] in EXACT_MATCHES:
            err = 0.0
        y = max(err, floor)
        pts.append((r["wall_seconds"], y))
        colour = colours[r["rung"]]
        ax.scatter(
            r["wall_seconds"],
            y,
            facecolors="none" if r["status"] == "what-if" else [colour],
            edgecolors=[colour],
            marker=markers.get(r["arch"], "o"),
            s=28,
            zorder=3,
        )
    front = pareto_front(pts)
    ax.plot([p[0] for p in front], [p[1] for p in front], "k--", lw=0.8, zorder=2)
    ax.axhline(floor, color="grey", lw=0.5, ls=":")
    _scale_axes(ax, pts, floor)
    ax.set_title(scene, fontsize=10)
    ax.set_xlabel("wall seconds per frame (log)")
    ax.set_ylabel("RMSE vs ideal golden (log; dotted: exact)")
    ax.grid(True, which="major", lw=0.3, alpha=0.5)


def _scale_axes(ax: Any, pts: list[tuple[float, float]], floor: float) -> None:
    """Log axes; an all-exact panel labels its floor ``exact``, and a panel within a decade
    of seconds labels its minor ticks."""
    from matplotlib.ticker import (
        FixedFormatter,
        FixedLocator,
        FormatStrFormatter,
        LogLocator,
        NullFormatter,
        NullLocator,
    )

    all_exact = all(y == floor for _, y in pts)
    if all_exact:  # no error to scale: one row of points on the floor, labelled so
        ax.set_ylim(floor / 3, floor * 3)
    ax.set_xscale("log")
    ax.set_yscale("log")
    if all_exact:
        ax.yaxis.set_major_locator(FixedLocator([floor]))
        ax.yaxis.set_major_formatter(FixedFormatter(["exact"]))
        ax.yaxis.set_minor_locator(NullLocator())
    xs = [p[0] for p in pts]
    if xs and max(xs) < 10 * min(xs):  # within a decade: label the minor ticks
        ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 3.0, 5.0)))  # none beside 10^k
        ax.xaxis.set_minor_formatter(FormatStrFormatter("%.2g"))
        ax.tick_params(axis="x", which="minor", labelsize=7, labelrotation=45)
    else:
        ax.xaxis.set_minor_formatter(NullFormatter())
