"""Skew address generator RTL on Amaranth's simulator, against models.units.skew."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units.skew import SkewConfig

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize(
    ("cfg", "n"),
    [
        (SkewConfig(), 256),  # VolumePro 500: P = 4 modules, 4 banks, full size
        (SkewConfig(), 200),  # padding rows (n not a multiple of P K)
        (SkewConfig(modules=3, banks=2, max_size=64), 37),  # non-power-of-two P, K
        (SkewConfig(modules=8, banks=4, max_size=64), 5),  # n < P
    ],
)
def test_addresses_equal_the_model(cfg, n):
    run_case(make_case("skew", cfg=cfg, n=n), count=400)
