"""Reflectance-map shader RTL on Amaranth's simulator, against models.units.shade."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units import shade as model
from models.units.shade import ShadeConfig
from rtl import shade

pytestmark = pytest.mark.rtl


def test_latency_and_interval_are_the_models():
    assert (shade.LATENCY, shade.II) == (model.LATENCY, model.II)


@pytest.mark.parametrize(
    "cfg",
    [
        ShadeConfig(method="reflectance-map", map_size=16),
        ShadeConfig(method="reflectance-map", map_size=5, normal_frac_bits=12),
    ],
)
def test_colours_equal_the_model(cfg):
    run_case(make_case("shade", cfg=cfg), count=250)


def test_phong_method_is_refused():
    with pytest.raises(ValueError, match="reflectance-map"):
        shade.Shade(ShadeConfig(method="phong"))
