"""The speed table as text: every row, and every case inside a row (each machine and
size, each rung, each renderer), against its goal, with the load it was measured under.

``benchmarks/speed_table.py`` and ``hwsim bench`` print :func:`format_rows`; the JSON
report holds the same figures (the printed table is for people: nothing parses it).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

from hwsim.studies.bench import TABLE_GOALS as GOALS
from hwsim.studies.bench import status_text

__all__ = ["format_rows", "load_text"]

#: The per-case goals of rows whose value is the worst of their cases: case key -> the
#: goal of the row whose value it is.
_CASE_VALUES = {
    "cycle_samples_per_s": "cycle_samples_per_s",
    "timing_only_vs_cycle": "timing_only_vs_cycle",
}
#: The timing-only rung's contract: its frame within 2 % of the cycle rung's cycles.
TIMING_CONTRACT = 0.02


def load_text(load: Sequence[float] | None = None) -> str:
    """``load average: 1.07, 1.20, 1.30`` (1, 5 and 15 minutes: what ``uptime`` prints),
    of ``load`` or of the machine now."""
    if load is None:
        load = os.getloadavg() if hasattr(os, "getloadavg") else None
    if load is None:
        return "load average: unknown"
    return "load average: " + ", ".join(f"{x:.2f}" for x in load)


def _show(value: float | None, unit: str) -> str:
    if value is None:
        return "-"
    if unit == "bytes":
        return f"{value / 1e9:.2f} GB"
    if unit == "samples/s":
        return f"{value / 1e6:.3g} M/s"
    return f"{value:.3g}x"


def _met(value: float | None, goal: float, better: str) -> str:
    if value is None:
        return "-"
    ok = value >= goal if better == "higher" else value <= goal
    return "yes" if ok else "no"


def _line(label: str, value: float | None, goal: float, better: str, unit: str, note: str) -> str:
    sign = ">=" if better == "higher" else "<="
    goal_text = f"{sign} {_show(goal, unit)}"
    met = _met(value, goal, better)
    return f"{label:<30}{_show(value, unit):>11}{goal_text:>12}  {met:<4}{note}"


def _case_lines(row: dict[str, Any]) -> list[str]:
    """One line per case of ``row`` against the row's goal."""
    name, out = row["row"], []
    goal, better, unit, _ = GOALS[name]
    for c in row.get("cases", ()):
        label = f"  {c['arch']} {c['size']}^3"
        if "status" in c:  # over the machine's memory, refused, failed
            out.append(f"{label:<30}{'-':>11}{'':>12}  {c['status']}")
            continue
        if name in _CASE_VALUES:
            key = _CASE_VALUES[name]
            note = ""
            if name == "timing_only_vs_cycle":
                err = c["timing_only_cycle_error"]
                inside = "within" if abs(err) <= TIMING_CONTRACT else "OUTSIDE"
                note = f"cycles {err:+.2%} ({inside} the 2 % contract)"
            out.append(_line(label, c[key], goal, better, unit, note))
        elif name == "cycle_512_peak_bytes":
            note = f"{c['peak_over_volume']:.1f}x the volume"
            out.append(_line(label, c["peak_rss_bytes"], goal, better, unit, note))
    for rung, r in row.get("rungs", {}).items():  # threads_2_vs_1
        s = r["seconds"]
        note = f"{s['1t']:.3f} s on one thread, {s['2t']:.3f} s on two"
        out.append(_line(f"  {rung}", r["speedup"], goal, better, unit, note))
    return out


def _row_note(row: dict[str, Any]) -> str:
    """What the row's value was computed from, in a few words."""
    parts = []
    if row.get("two_threads") is not None:
        parts.append(f"two threads {row['two_threads']:.3g}x")
    spf = row.get("seconds_per_frame")
    if spf:  # functional_vs_volpack
        parts.append(", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in spf.items()))
    elif row.get("seconds") and all(isinstance(v, float) for v in row["seconds"].values()):
        parts.append(", ".join(f"{k} {v:.3f} s" for k, v in row["seconds"].items()))
    before, after = row.get("load_average_before"), row.get("load_average_after")
    if before and after:
        parts.append(f"load {before[0]:.2f} -> {after[0]:.2f}")
    return "; ".join(parts)


def format_rows(
    rows: Sequence[dict[str, Any]], loads: tuple[Sequence[float], Sequence[float]] | None = None
) -> str:
    """The rows as a text table: each row's measured value, its goal and whether it is
    met, what it was computed from and the 1-minute load before and after it; under a
    row, each case (machine and size, rung) against the same goal.  ``loads``: the load
    averages at the start and the end of the run, printed first and last."""
    lines = []
    if loads is not None:
        lines.append(f"at the start: {load_text(loads[0])}")
    lines.append(f"{'row':<30}{'measured':>11}{'goal':>12}  met")
    for r in rows:
        if r["goal_met"] is None and r.get("value") is None:
            sign = ">=" if r["better"] == "higher" else "<="
            goal = f"{sign} {_show(r['goal'], r['unit'])}"
            lines.append(f"{r['row']:<30}{'-':>11}{goal:>12}  {status_text(r)}")
            continue
        met = {True: "yes", False: "no", None: status_text(r)}[r["goal_met"]]
        sign = ">=" if r["better"] == "higher" else "<="
        goal = f"{sign} {_show(r['goal'], r['unit'])}"
        value = _show(r.get("value"), r["unit"])
        lines.append(f"{r['row']:<30}{value:>11}{goal:>12}  {met:<4}{_row_note(r)}")
        lines.extend(_case_lines(r))
    if loads is not None:
        lines.append(f"at the end: {load_text(loads[1])}")
    return "\n".join(lines)
