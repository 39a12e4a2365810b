"""Smoke test of the VolPack reference harness (``benchmarks/volpack_reference.py``):
it builds and times VolPack's own example renderer when Debian's ``libvolpack1-dev`` is
installed (``./dev test`` installs it; CI must have it) and says why not otherwise.  It
checks the harness only: no wall-clock assertions."""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from benchmarks import volpack_reference as vr  # noqa: E402

pytestmark = pytest.mark.slow


def test_both_renderers_are_timed_per_frame(shared_data):
    missing = vr.volpack_available()
    if missing is not None and os.environ.get("CI") == "true":
        pytest.fail(f"{missing} (./dev test installs it)")
    report = vr.run(frames=2, repeats=1, image=32, volume=shared_data / "mr_brainsmall.nrrd")
    hw = report["hwsim"]
    assert hw["arch"] == "volumepro500" and math.isfinite(hw["seconds_per_frame"])
    assert hw["n_frame_run_seconds"] > 0 and hw["one_frame_run_seconds"] > 0
    if missing is None:
        vp = report["volpack"]
        assert vp["n_frame_run_seconds"] > 0 and math.isfinite(vp["seconds_per_frame"])
        assert report["volpack_missing"] is None and math.isfinite(report["ratio"])
    else:
        assert report["volpack"] is None and report["ratio"] is None


def test_without_volpack_the_harness_says_why(shared_data, tmp_path):
    report = vr.run(
        frames=2, repeats=1, image=16, examples=tmp_path / "absent",
        volume=shared_data / "mr_brainsmall.nrrd",
    )  # fmt: skip
    assert report["volpack"] is None and "libvolpack1-dev" in report["volpack_missing"]
