"""`hwsim render --fidelity cycle`: stats.json, the per-concern CSVs and the VCD trace."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from hwsim.cli import main

pytestmark = pytest.mark.system


def test_cycle_render_writes_exact_cycles_counters_csvs_and_a_trace(tmp_path, capsys):
    out, vcd = tmp_path / "run", tmp_path / "wave.vcd"
    args = ["render", "--phantom", "head:size=16", "--image", "20", "--arch", "cube4"]
    assert main([*args, "--fidelity", "cycle", "--out", str(out), "--trace", str(vcd)]) == 0
    assert "cycles at 125 MHz" in capsys.readouterr().out
    stats = json.loads((out / "stats.json").read_text())
    assert stats["fidelity"] == "cycle" and isinstance(stats["cycles"], int)
    assert stats["frame_seconds"] == pytest.approx(stats["cycles"] / 125e6)
    assert stats["counters"]["memory.conflicts"] == 0
    assert stats["derived"]["samples_per_cycle"] <= 4
    assert {"memory", "ring", "interp", "pixel_bus"} <= set(stats["elaborated_units"])
    rows = list(csv.DictReader((out / "units.csv").read_text().splitlines()))
    assert {r["unit"] for r in rows} >= {"interp", "composite", "shade"}
    assert all(int(r["total_cycles"]) == stats["cycles"] for r in rows)
    through = next(csv.DictReader((out / "throughput.csv").read_text().splitlines()))
    assert int(through["cycles"]) == stats["cycles"]
    assert "memory.conflicts" in (out / "memory.csv").read_text()
    text = vcd.read_text()
    assert "$enddefinitions $end" in text and "o__payload" in text and "i__valid" in text
    # The same scene at the functional rung gives the same image bits.
    assert main([*args, "--fidelity", "functional", "--out", str(tmp_path / "f"), "--quiet"]) == 0
    assert np.array_equal(np.load(out / "image.npy"), np.load(tmp_path / "f" / "image.npy"))


def test_archs_lists_every_machine_and_its_rungs(capsys):
    assert main(["archs"]) == 0
    text = capsys.readouterr().out
    for name in ("cube4", "cube4-teramac", "em-cube", "volumepro500", "volumepro1000", "vizard2"):
        assert name in text
    assert "golden functional transaction cycle" in text
