"""hwsim bench and the sweep-scaling harness: complete reports, missing rungs named.

Harness checks only: no wall-clock assertions (docs/conventions.md item 11).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.run.fidelity import FIDELITIES
from hwsim.studies.bench import GOALS, TABLE_GOALS, run_bench

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def test_every_rung_and_ratio_is_reported_and_missing_ones_say_so():
    # rtl_size 16: the RTL top's smallest size class (its build is the cosim tests').
    report = run_bench(16, 16, "volumepro500", 1, vtk=False, sweep=False, rows=(), rtl_size=16)
    assert set(report["rungs"]) == set(FIDELITIES)
    for r in report["rungs"].values():
        assert r["status"] == "ok" and r["seconds"] > 0 and r["samples_per_second"] > 0
    # volumepro500 is modelled at the cycle rung (issue 5): measured on itself, no note.
    assert report["rungs"]["cycle"]["arch"] == "volumepro500"
    assert "note" not in report["rungs"]["cycle"]
    txn = report["rungs"]["transaction"]
    assert txn["arch"] == "volumepro500" and "note" not in txn
    assert 0 < txn["timing_seconds"] < txn["seconds"] and txn["image_seconds"] > 0
    assert set(report["ratios"]) == set(GOALS)
    sweep = report["ratios"]["sweep_2_vs_1_workers"]
    assert sweep["status"] == "skipped" and sweep["note"] == "--no-sweep"
    assert report["table"] == []
    assert {"cpu_model", "usable_cores", "python", "numpy"} <= set(report["machine"])


def test_the_speed_table_rows_say_their_goal_and_whether_it_is_met():
    rows = ["functional_vs_golden", "cycle_samples_per_s", "timing_only_vs_cycle"]
    report = run_bench(
        16,
        16,
        "volumepro500",
        1,
        vtk=False,
        sweep=False,
        rows=rows,
        table_sizes=(16,),
        rtl_size=16,
    )
    table = {r["row"]: r for r in report["table"]}
    assert list(table) == rows
    for name, row in table.items():
        goal, better, _, _ = TABLE_GOALS[name]
        assert row["status"] == "ok" and row["value"] > 0 and row["goal"] == goal
        assert row["goal_met"] == (
            row["value"] >= goal if better == "higher" else row["value"] <= goal
        )
        assert len(row["load_average_before"]) == len(row["load_average_after"]) == 3
    fvg = table["functional_vs_golden"]
    assert fvg["value"] == pytest.approx(fvg["seconds"]["golden"] / fvg["seconds"]["functional"])
    cases = table["cycle_samples_per_s"]["cases"]
    assert {c["arch"] for c in cases} == {
        "cube4",
        "em-cube",
        "volumepro500",
        "volumepro1000",
        "vizard2",
    }
    assert table["cycle_samples_per_s"]["value"] == min(c["cycle_samples_per_s"] for c in cases)
    ratio = table["timing_only_vs_cycle"]
    assert ratio["value"] == min(c["cycle_seconds"] / c["timing_only_seconds"] for c in cases)
    # The timing-only rung's frame time is the cycle rung's within the 2 % contract.
    assert all(abs(c["timing_only_cycle_error"]) <= 0.02 for c in cases)


def test_vtk_rows_skipped_by_no_vtk_say_so(tmp_path):
    argv = ["bench", "--size", "16", "--image", "16", "--repeats", "1", "--no-vtk", "--no-sweep"]
    argv += ["--rtl-size", "16"]  # the RTL top's smallest size class (built by the cosim tests)
    argv += ["--rows", "golden_vs_vtk_first", "--out", str(tmp_path), "--quiet"]
    assert main(argv) == 0
    report = json.loads((tmp_path / "bench.json").read_text())
    (row,) = report["table"]
    assert (row["row"], row["status"], row["note"], row["goal_met"]) == (
        "golden_vs_vtk_first",
        "skipped",
        "--no-vtk",
        None,
    )


@pytest.mark.parametrize(
    "extra, key",
    [(["--rows", "fastest"], "--rows"), (["--table-sizes", "4"], "--table-sizes/--memory-size")],
)
def test_a_bad_row_or_size_is_refused_naming_the_flag(tmp_path, capsys, extra, key):
    argv = ["bench", "--size", "16", "--image", "16", "--no-vtk", "--no-sweep", *extra]
    assert main([*argv, "--out", str(tmp_path)]) != 0
    assert key in capsys.readouterr().err


def test_cli_bench_writes_json(tmp_path):
    argv = ["bench", "--size", "16", "--image", "16", "--repeats", "1", "--no-vtk", "--no-sweep"]
    argv += ["--rtl-size", "16"]  # the RTL top's smallest size class (built by the cosim tests)
    assert main([*argv, "--rows", "none", "--out", str(tmp_path), "--quiet"]) == 0
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
