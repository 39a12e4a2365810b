"""Smoke test of the benchmark harness (``benchmarks/bench_golden.py``).

Runs the benchmark's measurement path once on a 16^3 volume and a 16x16 image and checks
the JSON report has every key with a positive number.  It checks the harness only:
no wall-clock assertions (docs/conventions.md item 11).

VTK renders offscreen through EGL.  Without VTK or a working offscreen context the test
skips with the reason, except under CI (``CI=true``), which installs the ``bench`` extra
and must be able to render headless, so there it fails.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

PROBE = "from benchmarks.vtk_reference import vtk_environment; print(vtk_environment())"


def _require_vtk_offscreen() -> None:
    """Skip (fail under CI) unless VTK imports and opens an offscreen window.

    Probed in a subprocess: a missing EGL/OSMesa library can abort the process.
    """
    done = subprocess.run(
        [sys.executable, "-c", PROBE],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    if done.returncode == 0:
        return
    last = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
    reason = f"VTK offscreen rendering unavailable: {last}"
    if os.environ.get("CI") == "true":
        pytest.fail(reason + " (CI installs the bench extra and must render headless)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    _require_vtk_offscreen()
    from benchmarks import bench_golden

    out = tmp_path_factory.mktemp("bench") / "bench.json"
    status = bench_golden.main(
        [
            "--sizes",
            "16",
            "--images",
            "16",
            "--golden-repeats",
            "1",
            "--vtk-frames",
            "2",
            "--out",
            str(out),
        ]
    )
    assert status == 0
    return json.loads(out.read_text())


def _positive(record: dict[str, Any], *keys: str) -> None:
    for key in keys:
        value = record[key]
        assert isinstance(value, int | float) and not isinstance(value, bool), key
        assert math.isfinite(value) and value > 0, (key, value)


@pytest.mark.slow
def test_report_has_machine_and_vtk_figures(report: dict[str, Any]) -> None:
    assert report["schema"] == 1
    assert report["goal_ratio"] == 0.5
    machine = report["machine"]
    for key in ("cpu_model", "python", "numpy", "vtk", "vtk_window_class"):
        assert isinstance(machine[key], str) and machine[key], key
    _positive(machine, "cores", "usable_cores", "vtk_threads")
    assert "--sizes 16" in report["command"]

    (case,) = report["cases"]
    assert case["size"] == 16 and case["image"] == [16, 16]
    assert case["volume"]["shape"] == [16, 16, 16]
    _positive(case["volume"], "bytes")
    _positive(case["scene"], "sample_distance", "early_termination")
    vtk = case["vtk"]
    _positive(
        vtk,
        "seconds",
        "frames_per_second",
        "first_frame_seconds",
        "seconds_one_thread",
        "threads",
        "sample_distance",
        "peak_rss_bytes",
        "baseline_rss_bytes",
        "process_max_rss_bytes",
    )
    assert vtk["render_rss_bytes"] >= 0
    assert len(vtk["seconds_all"]) == 2


@pytest.mark.slow
def test_report_has_golden_figures_and_ratio(report: dict[str, Any]) -> None:
    assert report["golden_available"], "hwsim.golden.render_golden did not import"
    (case,) = report["cases"]
    golden = case["golden"]
    _positive(
        golden,
        "samples",
        "seconds",
        "samples_per_second",
        "frames_per_second",
        "peak_rss_bytes",
        "baseline_rss_bytes",
        "process_max_rss_bytes",
        "peak_rss_over_volume_bytes",
    )
    assert golden["render_rss_bytes"] >= 0
    _positive(case, "ratio", "ratio_vs_vtk_one_thread")
    assert isinstance(case["goal_met"], bool)
    assert case["goal_met"] == (case["ratio"] >= report["goal_ratio"])
    psnr = case["psnr_golden_vs_vtk_db"]
    assert psnr is None or math.isfinite(psnr)
