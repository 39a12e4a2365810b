"""The interpolation unit's RTL on Amaranth's simulator, against models.units.interp: the
trilinear interpolator, and the Cube-4 top's slice interpolator (``bilinear`` on three
slices, ``lerp`` for the edge rows and columns)."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units.interp import InterpConfig

pytestmark = pytest.mark.rtl

#: Widths and roundings both interpolators are checked at (defaults: VolumePro 500).
WIDTHS = [
    (InterpConfig(), 12),
    (InterpConfig(weight_bits=5, sample_frac_bits=2, rounding="nearest-even"), 8),
    (InterpConfig(weight_bits=5, sample_frac_bits=2, rounding="nearest-even"), 12),
    (InterpConfig(weight_bits=9, sample_frac_bits=1, rounding="truncate"), 16),
    (InterpConfig(weight_bits=3, sample_frac_bits=6, rounding="floor"), 12),
]


@pytest.mark.parametrize("unit", ["interp", "slice_interp"])
@pytest.mark.parametrize(("cfg", "voxel_bits"), [*WIDTHS, (InterpConfig(), 8)])
def test_samples_equal_the_model(unit, cfg, voxel_bits):
    run_case(make_case(unit, cfg=cfg, voxel_bits=voxel_bits), count=300)


@pytest.mark.parametrize("rounding", ["nearest-up", "nearest-even", "truncate", "floor"])
def test_signed_voxel_differences_equal_the_model(rounding):
    """Voxel-gradient source: signed B + 2-bit differences through the same lerps."""
    cfg = InterpConfig(rounding=rounding)
    run_case(make_case("interp", cfg=cfg, voxel_bits=14, signed_input=True), count=200)
