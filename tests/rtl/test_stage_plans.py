"""Each unit's latency is the RTL's own: the length of its stage plan (``STAGES`` in
rtl/<unit>.py), not a constant read from its model.  The cycle rungs time the units by
the model's ``LATENCY``; the unit benches (tests/rtl/amaranth_bench.py and the cocotb tier)
measure the RTL's handshake latency and compare it with that constant, and this file
compares the two constants and keeps the RTL from importing the model's: changing either
side alone fails."""

import ast
import importlib
from pathlib import Path

import pytest

from rtl import interp, slice_interp

pytestmark = pytest.mark.rtl

UNITS = ("skew", "interp", "gradient", "classify", "shade", "composite")
RTL = Path(__file__).resolve().parents[2] / "rtl"


@pytest.mark.parametrize("unit", UNITS)
def test_the_rtl_latency_is_its_stage_plan_and_equals_the_models(unit):
    rtl_unit = importlib.import_module(f"rtl.{unit}")
    model = importlib.import_module(f"models.units.{unit}")
    assert rtl_unit.LATENCY == len(rtl_unit.STAGES)
    assert rtl_unit.LATENCY == model.LATENCY, f"{unit}: RTL stages != the cycle rung's"
    assert rtl_unit.II == model.II == 1


@pytest.mark.parametrize("unit", [*UNITS, "slice_interp"])
def test_the_rtl_does_not_read_its_models_latency(unit):
    tree = ast.parse((RTL / f"{unit}.py").read_text())
    reads = [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute)
        and node.attr in ("LATENCY", "II")
        and isinstance(node.value, ast.Name)
        and node.value.id == "model"
    ]
    imports = [
        alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("models.")
        for alias in node.names
    ]
    assert not reads and "LATENCY" not in imports


def test_the_slice_interpolator_is_as_deep_as_the_interpolator():
    """The Cube-4 rungs time the top's slice interpolator as the interpolator."""
    assert slice_interp.LATENCY == interp.LATENCY >= len(slice_interp.STAGES)
