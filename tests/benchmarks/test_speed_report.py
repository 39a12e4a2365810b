"""The speed table's text: every row and every case in it against its goal, and the
load it ran under (benchmarks/speed_report.py)."""

from __future__ import annotations

import sys
from pathlib import Path

from hwsim.studies.bench import TABLE_GOALS

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks.speed_report import format_rows, load_text  # noqa: E402


def _row(name: str, value, **extra):
    goal, better, unit, definition = TABLE_GOALS[name]
    met = None if value is None else (value >= goal if better == "higher" else value <= goal)
    return {
        "row": name,
        "status": "ok",
        "value": value,
        "goal": goal,
        "better": better,
        "unit": unit,
        "definition": definition,
        "goal_met": met,
        "load_average_before": [1.5, 1.0, 0.5],
        "load_average_after": [2.25, 1.0, 0.5],
        **extra,
    }


def _case(arch, size, sps, ratio, err):
    return {
        "arch": arch,
        "size": size,
        "cycle_samples_per_s": sps,
        "timing_only_vs_cycle": ratio,
        "timing_only_cycle_error": err,
    }


def test_every_row_and_case_is_printed_against_its_goal_with_the_load():
    cases = [
        _case("cube4", 128, 9.1e6, 59.0, 0.001),
        _case("vizard2", 128, 0.064e6, 18.4, -0.03),
        {"arch": "em-cube", "size": 512, "status": "over the machine's memory"},
    ]
    rows = [
        _row(
            "functional_vs_volpack",
            0.075,
            two_threads=0.124,
            seconds_per_frame={"volpack": 0.0079, "functional_1t": 0.105, "functional_2t": 0.064},
        ),
        _row("cycle_samples_per_s", 0.064e6, cases=cases),
        _row("timing_only_vs_cycle", 18.4, cases=cases),
        _row(
            "threads_2_vs_1",
            1.0,
            rungs={"golden": {"seconds": {"1t": 1.0, "2t": 0.5}, "speedup": 2.0}},
        ),
        {**_row("golden_vs_vtk_first", None), "status": "skipped", "note": "--no-vtk"},
    ]
    text = format_rows(rows, ([0.5, 0.25, 0.125], [3.0, 2.0, 1.0]))
    lines = text.splitlines()
    assert lines[0] == "at the start: load average: 0.50, 0.25, 0.12"
    assert lines[-1] == "at the end: load average: 3.00, 2.00, 1.00"
    by_label: dict[str, list[list[str]]] = {}
    for line in lines[1:-1]:
        by_label.setdefault(line[:30].strip(), []).append(line[30:].split())
    assert by_label["functional_vs_volpack"][0][:4] == ["0.075x", ">=", "0.1x", "no"]
    assert "volpack 7.9 ms" in text and "functional_1t 105.0 ms" in text
    assert "two threads 0.124x" in text and "load 1.50 -> 2.25" in text
    # Each machine and size against the row's goal, once under each row that has it.
    speed, ratio = by_label["cube4 128^3"]
    assert speed[:6] == ["9.1", "M/s", ">=", "5", "M/s", "yes"]
    assert ratio[:4] == ["59x", ">=", "10x", "yes"]
    assert by_label["vizard2 128^3"][0][:6] == ["0.064", "M/s", ">=", "5", "M/s", "no"]
    assert "cycles -3.00% (OUTSIDE the 2 % contract)" in text
    assert "cycles +0.10% (within the 2 % contract)" in text
    assert text.count("em-cube 512^3") == 2 and "over the machine's memory" in text
    assert by_label["golden"][0][:4] == ["2x", ">=", "1.7x", "yes"]
    assert by_label["golden_vs_vtk_first"] == [["-", ">=", "0.5x", "skipped:", "--no-vtk"]]


def test_load_text_reads_like_uptime():
    assert load_text([1.0, 0.5, 0.25]) == "load average: 1.00, 0.50, 0.25"
    assert load_text().startswith("load average: ")


def test_hwsim_bench_prints_the_load_at_the_start_and_the_end():
    from hwsim.studies.bench import format_bench

    machine = {
        "cpu_model": "CPU",
        "usable_cores": 2,
        "load_average": [1.0, 0.5, 0.25],
        "load_average_after": [2.0, 1.5, 1.25],
    }
    lines = format_bench({"machine": machine, "rungs": {}, "table": [], "ratios": {}}).splitlines()
    assert lines[0] == "CPU, 2 usable cores, load average: 1.00, 0.50, 0.25"
    assert "at the end: load average: 2.00, 1.50, 1.25" in lines
