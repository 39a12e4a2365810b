"""Trilinear interpolator RTL on Amaranth's simulator, against models.units.interp."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units import interp as model
from models.units.interp import InterpConfig
from rtl import interp

pytestmark = pytest.mark.rtl


def test_latency_and_interval_are_the_models():
    assert (interp.LATENCY, interp.II) == (model.LATENCY, model.II)


@pytest.mark.parametrize(
    ("cfg", "voxel_bits"),
    [
        (InterpConfig(), 12),
        (InterpConfig(), 8),
        (InterpConfig(weight_bits=5, sample_frac_bits=2, rounding="nearest-even"), 12),
        (InterpConfig(weight_bits=9, sample_frac_bits=1, rounding="truncate"), 16),
        (InterpConfig(weight_bits=3, sample_frac_bits=6, rounding="floor"), 12),
    ],
)
def test_samples_equal_the_model(cfg, voxel_bits):
    run_case(make_case("interp", cfg=cfg, voxel_bits=voxel_bits), count=300)


@pytest.mark.parametrize("rounding", ["nearest-up", "nearest-even", "truncate", "floor"])
def test_signed_voxel_differences_equal_the_model(rounding):
    """Voxel-gradient source: signed B + 2-bit differences through the same lerps."""
    cfg = InterpConfig(rounding=rounding)
    run_case(make_case("interp", cfg=cfg, voxel_bits=14, signed_input=True), count=200)
