"""`hwsim render --fidelity cycle`: stats.json, the per-concern CSVs and the VCD trace, on
a slice machine (Cube-4) and the ray machine (VIZARD II); `hwsim archs` listing the rungs."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from hwsim.cli.commands import main

pytestmark = pytest.mark.system


def cycle_render(tmp_path, capsys, arch: str):
    """Render the small head at the cycle rung with a trace; check what every machine
    writes (exact cycles in stats, units.csv, the same image bits as the functional
    rung) and return (stats, output folder, VCD text, stdout)."""
    out, vcd = tmp_path / "run", tmp_path / "wave.vcd"
    args = ["render", "--phantom", "head:size=16", "--image", "20", "--arch", arch]
    assert main([*args, "--fidelity", "cycle", "--out", str(out), "--trace", str(vcd)]) == 0
    printed = capsys.readouterr().out
    stats = json.loads((out / "stats.json").read_text())
    assert stats["fidelity"] == "cycle" and isinstance(stats["cycles"], int)
    assert stats["counters"]["frame.cycles"] == stats["cycles"]
    rows = list(csv.DictReader((out / "units.csv").read_text().splitlines()))
    assert rows and all(int(r["total_cycles"]) == stats["cycles"] for r in rows)
    assert main([*args, "--fidelity", "functional", "--out", str(tmp_path / "f"), "--quiet"]) == 0
    assert np.array_equal(np.load(out / "image.npy"), np.load(tmp_path / "f" / "image.npy"))
    return stats, out, vcd.read_text(), printed


def test_cube4_cycle_render_writes_exact_cycles_counters_csvs_and_a_trace(tmp_path, capsys):
    stats, out, vcd, printed = cycle_render(tmp_path, capsys, "cube4")
    assert "cycles at 125 MHz" in printed
    assert stats["frame_seconds"] == pytest.approx(stats["cycles"] / 125e6)
    assert stats["counters"]["memory.conflicts"] == 0
    assert stats["derived"]["samples_per_cycle"] <= 4
    assert {"memory", "ring", "interp", "pixel_bus"} <= set(stats["elaborated_units"])
    rows = list(csv.DictReader((out / "units.csv").read_text().splitlines()))
    assert {r["unit"] for r in rows} >= {"interp", "composite", "shade"}
    through = next(csv.DictReader((out / "throughput.csv").read_text().splitlines()))
    assert int(through["cycles"]) == stats["cycles"]
    assert "memory.conflicts" in (out / "memory.csv").read_text()
    assert "$enddefinitions $end" in vcd and "o__payload" in vcd and "i__valid" in vcd


def test_vizard2_cycle_render_writes_exact_cycles_and_cache_counters(tmp_path, capsys):
    stats, _, vcd, printed = cycle_render(tmp_path, capsys, "vizard2")
    assert "cycles at 100 MHz" in printed
    c, derived = stats["counters"], stats["derived"]
    assert derived["hit_rates"]["cache"] == pytest.approx(c["cache.hits"] / c["cache.lookups"])
    assert 0 < derived["hit_rates"]["cache"] < 1
    assert c["memory.bursts"] > 0 and derived["samples_per_cycle"] <= 1
    assert "$enddefinitions $end" in vcd and "i__payload" in vcd and "o__valid" in vcd


def test_archs_lists_every_machine_and_its_rungs(capsys):
    assert main(["archs"]) == 0
    text = capsys.readouterr().out
    for name in ("cube4", "cube4-teramac", "em-cube", "volumepro500", "volumepro1000", "vizard2"):
        assert name in text
    assert "golden functional transaction cycle" in text
    line = next(x for x in text.splitlines() if x.lstrip().startswith("vizard2"))
    assert "cycle" in line
