"""hwsim bench and the sweep-scaling harness: complete reports, missing rungs named.

Harness checks only: no wall-clock assertions (docs/conventions.md item 11).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from hwsim.bench import GOALS, run_bench
from hwsim.cli import main
from hwsim.fidelity import FIDELITIES

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def test_every_rung_and_ratio_is_reported_and_missing_ones_say_so():
    report = run_bench(16, 16, "volumepro500", 1, vtk=False, sweep=False)
    assert set(report["rungs"]) == set(FIDELITIES)
    for r in report["rungs"].values():
        assert r["status"] == "ok" and r["seconds"] > 0 and r["samples_per_second"] > 0
    # volumepro500 is modelled at the cycle rung (issue 5): measured on itself, no note.
    assert report["rungs"]["cycle"]["arch"] == "volumepro500"
    assert "note" not in report["rungs"]["cycle"]
    txn = report["rungs"]["transaction"]
    assert txn["arch"] == "volumepro500" and "note" not in txn
    assert 0 < txn["timing_seconds"] < txn["seconds"] and txn["image_seconds"] > 0
    ratios = report["ratios"]
    assert set(ratios) == set(GOALS)
    fvg = ratios["functional_vs_golden"]
    assert fvg["status"] == "ok" and fvg["value"] > 0
    assert fvg["value"] == pytest.approx(fvg["golden_seconds"] / fvg["functional_seconds"])
    # transaction_vs_cycle compares one machine: the transaction rung is timed again on
    # the machine the cycle rung ran on when the two differ.
    tvc, cyc_rung = ratios["transaction_vs_cycle"], report["rungs"]["cycle"]
    pair = txn.get("paired_with_cycle", txn)
    assert tvc["arch"] == pair["arch"] == cyc_rung["arch"]
    assert tvc["value"] == pytest.approx(cyc_rung["seconds"] / pair["seconds"])
    assert tvc["timing_model_vs_cycle"] == pytest.approx(
        report["rungs"]["cycle"]["seconds"] / tvc["timing_model_seconds"]
    )
    cyc = report["rungs"]["cycle"]
    assert ratios["cycle_samples_per_second"]["value"] == cyc["samples_per_second"]
    assert ratios["golden_vs_vtk"]["note"] == "skipped (--no-vtk)"
    assert {"cpu_model", "usable_cores", "python", "numpy"} <= set(report["machine"])


def test_cli_bench_writes_json(tmp_path):
    argv = ["bench", "--size", "16", "--image", "16", "--repeats", "1", "--no-vtk", "--no-sweep"]
    assert main([*argv, "--out", str(tmp_path), "--quiet"]) == 0
    report = json.loads((tmp_path / "bench.json").read_text())
    assert report["rungs"]["golden"]["status"] == "ok"


@pytest.mark.slow
def test_sweep_scaling_harness_reports_a_speedup_per_worker_count():
    from benchmarks.bench_sweep import run

    report = run(size=16, workers=(1, 2), repeats=1)
    assert [c["workers"] for c in report["cases"]] == [1, 2]
    assert all(c["ok"] == 24 and c["failed"] == 0 for c in report["cases"])
    one, two = report["cases"]
    assert report["speedup_2_workers"] == pytest.approx(one["sweep_seconds"] / two["sweep_seconds"])
