"""Compositor RTL (opacity correction, front-to-back, ERT flag, MIP) on Amaranth's
simulator, against models.units.composite."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units.composite import CompositeConfig

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize(
    ("cfg", "k", "threshold"),
    [
        (CompositeConfig(), 1.0, 0.95),  # identity correction table
        (CompositeConfig(), 1.7, 1.0),  # ERT off
        (CompositeConfig(acc_frac_bits=12, ratio_frac_bits=4), 0.5, 0.5),
        (CompositeConfig(acc_frac_bits=24), 3.25, 0.999),
    ],
)
def test_accumulators_equal_the_model(cfg, k, threshold):
    run_case(make_case("composite", cfg=cfg, k=k, threshold=threshold), count=300)
