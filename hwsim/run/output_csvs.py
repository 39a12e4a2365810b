"""One CSV per concern for timed runs: ``throughput.csv``, ``units.csv``, ``memory.csv``.

Built only from the raw counters a rung returns (component paths such as
``pipeline[2].interp.busy_cycles``) and the frame totals, so downstream tools read
numbers, never text (conventions.md item 7).  Each is written to a temporary name and
renamed into place (:func:`hwsim.core.paths.atomic_write`).
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import TYPE_CHECKING

from hwsim.core.paths import atomic_write

if TYPE_CHECKING:
    from hwsim.run.fidelity import RenderRun

__all__ = ["write_csvs", "unit_rows"]

_UNIT = re.compile(r"^pipeline\[(\d+)\]\.(\w+)\.(\w+)$")
_KINDS = ("busy_cycles", "stall_cycles", "idle_cycles", "inputs")


def unit_rows(counters: dict[str, int]) -> list[dict[str, int | str]]:
    """Per pipeline and unit: busy, stall and idle cycles, inputs, and their total."""
    table: dict[tuple[int, str], dict[str, int | str]] = {}
    for path, value in counters.items():
        m = _UNIT.match(path)
        if m and m.group(3) in _KINDS:
            row = table.setdefault((int(m.group(1)), m.group(2)), {})
            row[m.group(3)] = value
    rows = []
    for (lane, unit), row in sorted(table.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        total = sum(int(row.get(k, 0)) for k in _KINDS[:3])
        rows.append(
            {
                "unit": unit,
                "pipeline": lane,
                **{k: row.get(k, 0) for k in _KINDS},
                "total_cycles": total,
            }
        )
    return rows


def write_csvs(run: RenderRun, out: Path) -> dict[str, Path]:
    """Write the three CSVs of a run that has a cycle count; returns their paths."""
    if run.cycles is None:
        return {}
    paths = {k: out / f"{k}.csv" for k in ("throughput", "units", "memory")}
    seconds = run.cycles / run.clock_hz if run.clock_hz else None
    with atomic_write(paths["throughput"]) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "fidelity",
                "arch",
                "samples",
                "cycles",
                "clock_hz",
                "samples_per_cycle",
                "frame_seconds",
                "samples_per_second",
                "wall_seconds",
            ]
        )
        w.writerow(
            [
                run.fidelity,
                run.arch,
                run.samples,
                run.cycles,
                run.clock_hz,
                run.samples / run.cycles if run.cycles else 0.0,
                seconds,
                run.samples / seconds if seconds else None,
                run.wall_seconds,
            ]
        )
    rows = unit_rows(run.counters)
    energy = run.silicon["energy"]["units"] if run.silicon else {}
    area = run.silicon["area"]["units"] if run.silicon else {}
    for row in rows:  # each pipeline's share: its own actions, one unit's silicon
        unit = str(row["unit"])
        if unit in energy:
            row["energy_joules"] = int(row.get("inputs", 0)) * energy[unit]["joules_per_action"]
        if unit in area:
            row["area_mm2"] = area[unit]["per_pipeline_mm2"]
    with atomic_write(paths["units"]) as tmp, open(tmp, "w", newline="") as fh:
        fields = ["unit", "pipeline", *_KINDS, "total_cycles", "energy_joules", "area_mm2"]
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    with atomic_write(paths["memory"]) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["counter", "value"])
        for path, value in run.counters.items():
            if path.startswith(("memory.", "ring.", "slice_fifo.", "pixel_bus.")):
                w.writerow([path, value])
        if run.silicon:  # hwsim.energy: each memory's energy, each buffer's area
            for store, entry in run.silicon["energy"]["memories"].items():
                w.writerow([f"energy.{store}.joules", entry["joules"]])
            for name, entry in run.silicon["area"]["buffers"].items():
                w.writerow([f"area.{name}.mm2", entry["mm2"]])
    return paths
