"""Classifier RTL (LUT with load port, expansion, magnitude modulation) on Amaranth's
simulator, against models.units.classify."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units.classify import ClassifyConfig

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize(
    ("cfg", "voxel_bits", "modulate"),
    [
        (ClassifyConfig(), 12, True),
        (ClassifyConfig(), 12, False),
        (ClassifyConfig(entries=256, color_bits=5, alpha_bits=7, gm_entries=16), 8, True),
        (ClassifyConfig(entries=1024, color_bits=12, alpha_bits=12, gm_entries=4096), 16, True),
    ],
)
def test_rgba_equals_the_model(cfg, voxel_bits, modulate):
    run_case(make_case("classify", cfg=cfg, voxel_bits=voxel_bits, modulate=modulate), count=300)
