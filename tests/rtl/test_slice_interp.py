"""The top's slice interpolator on Amaranth's simulator, against models.units.interp
(``bilinear`` on three slices, ``lerp`` for the edge rows and columns)."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units import interp as model
from models.units.interp import InterpConfig
from rtl import slice_interp

pytestmark = pytest.mark.rtl


def test_latency_and_interval_are_the_interpolators():
    assert (slice_interp.LATENCY, slice_interp.II) == (model.LATENCY, model.II)


@pytest.mark.parametrize(
    ("cfg", "voxel_bits"),
    [
        (InterpConfig(), 12),
        (InterpConfig(weight_bits=5, sample_frac_bits=2, rounding="nearest-even"), 8),
        (InterpConfig(weight_bits=9, sample_frac_bits=1, rounding="truncate"), 16),
        (InterpConfig(weight_bits=3, sample_frac_bits=6, rounding="floor"), 12),
    ],
)
def test_samples_and_edge_lerps_equal_the_model(cfg, voxel_bits):
    run_case(make_case("slice_interp", cfg=cfg, voxel_bits=voxel_bits), count=300)
