"""benchmarks/split_frame.py: the scaling table's harness on a small frame (no wall-clock
assertions: docs/conventions.md item 11), on the head phantom and on the real CT."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

pytestmark = pytest.mark.system


@pytest.mark.parametrize("volume", ["head", "ct"])
def test_the_table_checks_one_and_two_workers_against_one_process(volume, tmp_path, request):
    from benchmarks import split_frame

    if volume == "ct":
        request.getfixturevalue("shared_data")  # skipped without ../shared (fails on CI)
    out = tmp_path / "split.json"
    argv = ["--sizes", "16", "--workers", "1", "2", "--reference-max", "16", "--volume", volume]
    assert split_frame.main([*argv, "--scratch", str(tmp_path), "--out", str(out)]) == 0
    report = json.loads(out.read_text())
    (check,) = report["checks"]
    assert check["identical"] and check["compared"] == ["one process", "1 workers", "2 workers"]
    # The image's equality is evidence, the cycles' and counters' holds by construction:
    # the check keeps them apart and says which is which.
    assert check["image_identical"] and check["cycles_and_counters_identical"]
    assert check["independence"]["image"].startswith("evidence")
    assert check["independence"]["cycles_and_counters"].startswith("by construction")
    rows = report["rows"]
    assert [(r["workers"], r["phase"]) for r in rows] == [
        (None, "one process"),
        (1, "cold"),
        (1, "warm"),
        (2, "cold"),
        (2, "warm"),
    ]
    for row in rows:
        assert row["samples"] == 16**3 and row["samples_per_second"] > 0
        assert len(row["worker_peak_rss_bytes"]) == (row["workers"] or 0)
    assert set(report["speedup_2_vs_1"]) == {"16^3 cold", "16^3 warm"}
    assert not list(tmp_path.glob("**/ct-16.npy"))  # the scratch volume is removed
