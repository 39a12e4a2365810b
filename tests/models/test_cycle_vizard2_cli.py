"""`hwsim render --fidelity cycle --arch vizard2` end to end, and `hwsim archs` listing it."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from hwsim.cli import main

pytestmark = pytest.mark.system


def test_vizard2_cycle_render_writes_exact_cycles_and_cache_counters(tmp_path, capsys):
    out, vcd = tmp_path / "run", tmp_path / "wave.vcd"
    args = ["render", "--phantom", "head:size=16", "--image", "20", "--arch", "vizard2"]
    assert main([*args, "--fidelity", "cycle", "--out", str(out), "--trace", str(vcd)]) == 0
    assert "cycles at 100 MHz" in capsys.readouterr().out
    stats = json.loads((out / "stats.json").read_text())
    assert stats["fidelity"] == "cycle" and isinstance(stats["cycles"], int)
    c, derived = stats["counters"], stats["derived"]
    assert c["frame.cycles"] == stats["cycles"]
    assert derived["hit_rates"]["cache"] == pytest.approx(c["cache.hits"] / c["cache.lookups"])
    assert 0 < derived["hit_rates"]["cache"] < 1
    assert c["memory.bursts"] > 0 and derived["samples_per_cycle"] <= 1
    rows = list(csv.DictReader((out / "units.csv").read_text().splitlines()))
    assert rows and all(int(r["total_cycles"]) == stats["cycles"] for r in rows)
    text = vcd.read_text()
    assert "$enddefinitions $end" in text and "i__payload" in text and "o__valid" in text
    assert main([*args, "--fidelity", "functional", "--out", str(tmp_path / "f"), "--quiet"]) == 0
    assert np.array_equal(np.load(out / "image.npy"), np.load(tmp_path / "f" / "image.npy"))


def test_archs_shows_the_vizard2_cycle_rung(capsys):
    assert main(["archs"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.lstrip().startswith("vizard2"))
    assert "cycle" in line
