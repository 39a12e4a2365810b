"""Reflectance-map shader RTL on Amaranth's simulator, against models.units.shade."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units.shade import ShadeConfig
from rtl import shade

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize(
    "cfg",
    [
        ShadeConfig(method="reflectance-map", map_size=16),
        ShadeConfig(method="reflectance-map", map_size=5, normal_frac_bits=12),
    ],
)
def test_reflectance_map_colours_equal_the_model(cfg):
    run_case(make_case("shade", cfg=cfg), count=250)


@pytest.mark.parametrize(
    ("cfg", "lights"),
    [
        (ShadeConfig(method="phong"), 2),
        (ShadeConfig(method="phong", normal_frac_bits=5, spec_table_entries=64), 1),
        (ShadeConfig(method="phong", normal_frac_bits=14, spec_table_entries=4096), 3),
    ],
)
def test_phong_colours_equal_the_model(cfg, lights):
    run_case(make_case("shade", cfg=cfg, lights=lights), count=250)


def test_no_light_is_refused():
    with pytest.raises(ValueError, match="lights"):
        shade.Shade(ShadeConfig(method="phong"), lights=0)
