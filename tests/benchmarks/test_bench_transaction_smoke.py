"""Smoke test of the transaction-rung harnesses (``benchmarks/bench_transaction.py``,
``benchmarks/transaction_error.py``): complete reports, no wall-clock assertions."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def test_bench_transaction_reports_both_rungs_and_the_event_model_apart():
    from benchmarks.bench_transaction import GOAL, measure

    case = measure(16, "perspective", 1)
    assert case["identical_images"] is True and case["goal"] == GOAL
    for key in ("cycle_seconds", "transaction_seconds", "timing_model_seconds", "image_seconds"):
        assert case[key] > 0, key
    assert case["timing_model_seconds"] < case["transaction_seconds"]
    assert case["transaction_vs_cycle"] == pytest.approx(
        case["cycle_seconds"] / case["transaction_seconds"]
    )
    assert case["cycle_error"] == pytest.approx(
        case["transaction_cycles"] / case["cycle_cycles"] - 1
    )
    assert case["timing_only_cycles_equal"] is True and case["timing_only_seconds"] > 0
    assert case["timing_only_vs_cycle"] == pytest.approx(
        case["cycle_seconds"] / case["timing_only_seconds"]
    )


def test_error_table_measures_a_case_and_says_when_it_cannot_compare():
    from benchmarks.transaction_error import cases, measure
    from models.cycle import has_cycle_model

    quick = cases(quick=True)
    row = measure(quick[0])
    assert row["error"] == pytest.approx(row["transaction_cycles"] / row["cycle_cycles"] - 1)
    vp = next(c for c in quick if c["arch"].name == "volumepro500")
    vp_row = measure(vp)
    if has_cycle_model(vp["arch"]):
        assert vp_row["error"] is not None
    else:
        assert vp_row["error"] is None and vp_row["note"].startswith("not yet compared")
    # Every row names its independence: Cube-4's rungs share the timing functions, so its
    # row is a consistency check, never shown as a number; VolumePro's are partly shared.
    assert (row["comparison"], row["independence"]) == ("cube4", "shared")
    assert row["error_shown"].startswith("consistency check (shared code: cube4_latency")
    assert (vp_row["comparison"], vp_row["independence"]) == ("volumepro", "partly shared")
    assert vp_row["error_shown"].endswith("%") or vp_row["error"] is None
    # Every machine's row is measured, whatever its transaction model counts: VIZARD II's
    # default is a packet model with no events (the table once stopped on its row).
    for name in ("vizard2", "volumepro1000"):
        other = measure(next(c for c in quick if c["arch"].name == name))
        assert other["error"] == pytest.approx(
            other["transaction_cycles"] / other["cycle_cycles"] - 1
        )
        assert abs(other["error"]) <= 0.02 and other["granularity"]


def test_the_error_table_gains_its_independence_columns_without_re_measuring():
    """``annotate`` adds the verdicts to an existing report from its numbers alone."""
    from benchmarks.transaction_error import annotate, cases

    quick = {c["name"]: c for c in cases(quick=True)}
    names = ["head48 parallel 0,0 img48 P4", "head32 parallel 0,0 volumepro500"]
    names.append(next(n for n in quick if n.endswith("vizard2")))
    rows = [
        {"case": n, "arch": quick[n]["arch"].name, "projection": "parallel", "error": e}
        for n, e in zip(names, [0.05, 0.003, -0.01], strict=True)
    ]
    report = annotate({"schema": 1, "cases": rows}, {n: quick[n]["arch"] for n in names})
    shown = [r["independence"] for r in report["cases"]]
    # VIZARD II's rung times on a packet model of its own (issue 36, packet_timing.py),
    # sharing the plan and the termination steps with the cycle rung: partly shared.
    assert shown == ["shared", "partly shared", "partly shared"]
    # A shared row's number is no measurement: the largest measured error leaves it out.
    assert report["max_abs_error"] == 0.05 and report["max_abs_error_not_shared"] == 0.01
    assert set(report["independence"]) == {"cube4", "volumepro", "vizard2"}
    assert report["independence"]["cube4"]["shared"][0].endswith("cube4_latency")
    assert report["worst"]["cube4-P4 parallel"]["error_shown"].startswith("consistency check")
