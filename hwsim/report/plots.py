"""Report plots (matplotlib Agg): image triples, unit utilisation, stalls, bandwidth.

Every function takes raw data and a PNG path and returns the path, or ``None`` when the
data holds nothing to plot, so the report can say "not recorded" instead of drawing an
empty axis.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.config import flatten_table
from hwsim.core.paths import atomic_write
from hwsim.run.output import image_to_rgb8

__all__ = [
    "unit_counters",
    "memory_counters",
    "plot_images",
    "plot_utilisation",
    "plot_stalls",
    "plot_bandwidth",
    "RUN_PLOTS",
    "plot_path",
]

#: The plots a report may draw for each run folder, ``run{index}-{kind}.png``; a trade
#: folder's plot is copied as ``trade-{index}.png``.  :func:`plot_path` is the one place
#: a plot is named, so the report can list every PNG before it draws one.
RUN_PLOTS = ("images", "utilisation", "stalls", "bandwidth", "energy", "area")


def plot_path(out: Path, kind: str, index: int) -> Path:
    """Where the report draws plot ``kind`` (one of :data:`RUN_PLOTS`, or ``"trade"``)
    of its ``index``-th run or trade folder."""
    if kind == "trade":
        return Path(out) / f"trade-{index}.png"
    if kind not in RUN_PLOTS:
        raise ValueError(f"unplanned plot {kind!r}")
    return Path(out) / f"run{index}-{kind}.png"


_UNIT_COUNTER = re.compile(
    r"^(?P<unit>.+)\.(?P<kind>busy|stall|idle)(?:_cycles|\.(?P<why>[\w-]+))?$"
)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def unit_counters(counters: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Per-unit busy/stall/idle cycles from raw counters.

    Recognised paths (design conventions item 7): ``<unit>.busy_cycles``,
    ``<unit>.idle_cycles``, ``<unit>.stall_cycles`` and ``<unit>.stall.<reason>``
    (cycles stalled for one reason), e.g. ``pipeline[2].interp.busy_cycles``.
    """
    units: dict[str, dict[str, float]] = {}
    for path, value in flatten_table(counters).items():
        m = _UNIT_COUNTER.match(path)
        if m is None or not isinstance(value, (int, float)):
            continue
        name = m["kind"] if m["why"] is None else f"stall:{m['why']}"
        units.setdefault(m["unit"], {})[name] = float(value)
    return units


def memory_counters(counters: dict[str, Any]) -> dict[str, float]:
    """Byte counters of the memory system: paths under ``memory`` ending in ``bytes``."""
    return {
        path: float(v)
        for path, v in flatten_table(counters).items()
        if path.startswith("memory") and path.endswith("bytes") and isinstance(v, (int, float))
    }


def plot_images(
    simulated: np.ndarray, reference: np.ndarray | None, path: Path, titles: tuple[str, str]
) -> Path:
    """Reference, simulated and ``|simulated - reference|`` (max over channels) heat map."""
    plt = _plt()
    panels = 3 if reference is not None else 1
    fig, axes = plt.subplots(1, panels, figsize=(3.4 * panels, 3.4), squeeze=False)
    ax = axes[0]
    if reference is None:
        ax[0].imshow(image_to_rgb8(simulated)[0])
        ax[0].set_title(titles[1], fontsize=9)
    else:
        ax[0].imshow(image_to_rgb8(reference)[0])
        ax[0].set_title(titles[0], fontsize=9)
        ax[1].imshow(image_to_rgb8(simulated)[0])
        ax[1].set_title(titles[1], fontsize=9)
        diff = np.abs(np.asarray(simulated, float) - np.asarray(reference, float))
        if diff.ndim == 3:
            diff = diff.max(axis=2)
        im = ax[2].imshow(diff, cmap="inferno")
        ax[2].set_title(f"|difference| (max {diff.max():.3g})", fontsize=9)
        fig.colorbar(im, ax=ax[2], fraction=0.046, pad=0.04)
    for a in ax:
        a.set_xticks([])
        a.set_yticks([])
    fig.tight_layout()
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=100)
    plt.close(fig)
    return path


#: Longest line of a bar's label before it wraps (after a ``.`` of its path).
LABEL_CHARS = 30


def _wrap(name: str, width: int = LABEL_CHARS) -> str:
    """``name`` broken into lines of at most ``width`` characters where it can be: after a
    ``.`` of its path (``memory.sdram.bank_queue`` -> ``memory.sdram.`` / ``bank_queue``)."""
    parts = re.findall(r"[^.]*\.?", name)
    lines = [""]
    for part in (p for p in parts if p):
        if lines[-1] and len(lines[-1]) + len(part) > width:
            lines.append("")
        lines[-1] += part
    return "\n".join(lines)


def _compact(value: float, _pos: int = 0) -> str:
    """An axis number in at most a few characters: ``250k``, ``1.5M``, ``4,000``, ``0.25``."""
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e4, "k")):
        if abs(value) >= scale:
            shown = value / (scale if suffix != "k" else 1e3)
            return f"{shown:.3g}{suffix}"
    return f"{value:,.4g}"


def _bar_figure(names: list[str], xlabel: str, draw):
    """Horizontal bars, one per name (first at the top); ``draw(ax)`` adds the bars.

    Labels wrap (:func:`_wrap`) and the figure grows with their lines, the value axis
    carries at most six compact numbers, and a legend sits outside the bars, so nothing
    overlaps however many units a machine has."""
    plt = _plt()
    labels = [_wrap(n) for n in names]
    lines = sum(label.count("\n") + 1 for label in labels)
    fig, ax = plt.subplots(figsize=(6.5, 0.22 * lines + 0.13 * len(names) + 1.3))
    draw(ax)
    ax.set_yticks(range(len(names)), labels, fontsize=8)
    ax.set_xlabel(xlabel)
    if ax.get_xscale() == "linear":
        from matplotlib.ticker import FuncFormatter, MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
        ax.xaxis.set_major_formatter(FuncFormatter(_compact))
    ax.set_ylim(len(names) - 0.5, -0.5)  # first name at the top
    return fig


def _save(fig, path: Path) -> Path:
    """Write ``fig`` as PNG, cropped to everything drawn (legends outside the axes)."""
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=100, bbox_inches="tight")
    _plt().close(fig)
    return path


def _bars(path: Path, names: list[str], xlabel: str, draw) -> Path:
    return _save(_bar_figure(names, xlabel, draw), path)


def plot_utilisation(units: dict[str, dict[str, float]], cycles: int, path: Path) -> Path | None:
    """Busy cycles / total cycles per unit, as horizontal bars."""
    busy = {u: c["busy"] / cycles for u, c in units.items() if "busy" in c and cycles}
    if not busy:
        return None
    names = list(busy)

    def draw(ax) -> None:
        ax.barh(names, [busy[n] * 100 for n in names], color="tab:blue")
        ax.set_xlim(0, 100)

    return _bars(path, names, "utilisation (% of cycles busy)", draw)


def plot_stalls(units: dict[str, dict[str, float]], path: Path) -> Path | None:
    """Stall cycles per unit, stacked by reason (``stall`` alone when no reason given)."""
    reasons = sorted({k for c in units.values() for k in c if k.startswith("stall")})
    stalled = {u: c for u, c in units.items() if any(c.get(r, 0) for r in reasons)}
    if not stalled:
        return None
    names = list(stalled)

    def draw(ax) -> None:
        left = np.zeros(len(names))
        for reason in reasons:
            widths = np.array([stalled[n].get(reason, 0.0) for n in names])
            if widths.any():
                ax.barh(names, widths, left=left, label=reason.removeprefix("stall:"))
                left += widths
        # Beside the bars, not over them.
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)

    return _bars(path, names, "stall cycles", draw)


def plot_bandwidth(memory: dict[str, float], seconds: float, path: Path) -> Path | None:
    """Bytes per simulated second for each memory counter."""
    if not memory or not seconds:
        return None
    names = list(memory)

    def draw(ax) -> None:
        ax.barh(names, [memory[n] / seconds / 1e9 for n in names], color="tab:green")

    return _bars(path, names, "GB/s at the simulated clock", draw)


def plot_energy(energy: dict[str, Any], path: Path) -> Path | None:
    """Energy of one frame by unit, memory and leakage (uJ), as horizontal bars."""
    parts = {f"unit: {u}": e["joules"] for u, e in energy.get("units", {}).items()}
    parts.update({f"memory: {m}": e["joules"] for m, e in energy.get("memories", {}).items()})
    parts["static (leakage)"] = energy.get("static_joules", 0.0)
    if not any(parts.values()):
        return None
    names = list(parts)

    def draw(ax) -> None:
        ax.barh(names, [parts[n] * 1e6 for n in names], color="tab:orange")

    return _bars(path, names, "energy per frame (uJ)", draw)


def plot_area(area: dict[str, Any], path: Path) -> Path | None:
    """Area of every pipeline's units and of the buffers (mm^2), as horizontal bars."""
    parts = {f"units: {u}": a["mm2"] for u, a in area.get("units", {}).items()}
    parts.update({f"buffer: {b}": a["mm2"] for b, a in area.get("buffers", {}).items()})
    if not parts:
        return None
    names = list(parts)

    def draw(ax) -> None:
        ax.barh(names, [parts[n] for n in names], color="tab:purple")
        ax.set_xscale("log")

    return _bars(path, names, "area (mm^2, log scale)", draw)
