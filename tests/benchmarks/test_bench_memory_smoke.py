"""Smoke test of ``benchmarks/bench_memory.py``: the harness writes a complete report.

Checks the harness only, on tiny volumes: no wall-clock assertions (conventions item 11).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

pytestmark = pytest.mark.model


def test_memory_benchmark_report(tmp_path, capsys):
    from benchmarks import bench_memory

    out = tmp_path / "memory.json"
    args = ["--size", "16", "--simpy-size", "8", "--layout-size", "16", "--out", str(out)]
    assert bench_memory.main(args) == 0
    report = json.loads(out.read_text())
    assert report["schema"] == 1 and report["benchmark"] == "memory"
    cycle = report["speed"]["cycle"]
    assert len(cycle) == 4 and all(c["cycle_bursts_per_second"] > 0 for c in cycle)
    for c in report["speed"]["simpy_vs_cycle"]:
        assert c["simpy_bursts_per_second"] > 0 and c["same_completion_cycles"] is True
        assert c["port_bursts_per_second"] > 0
    layouts = {(r["layout"], r["axis"]) for r in report["layouts"]}
    assert ("volumepro500", "y") in layouts and ("no bank skew (block)", "x") in layouts
    for r in report["layouts"]:
        assert 0 < r["efficiency"] <= 1
    assert "efficiency" in capsys.readouterr().out
