"""Gradient unit RTL (differences, to_world, magnitude, normals) on Amaranth's simulator,
against models.units.gradient.  The unit's deep square-root and divider logic is slow in
the Python simulator: few vectors here, 10^4 per simulator in tests/cosim."""

import pytest
from amaranth_bench import run_case
from unit_cases import make_case

from models.units.gradient import GradientConfig

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize(
    ("cfg", "sample_bits", "spacing"),
    [
        (GradientConfig(), 16, (1.0, 1.0, 1.0)),  # isotropic: to_world is the identity
        (GradientConfig(normal_frac_bits=6), 12, (1.0, 0.7, 1.3)),
        (GradientConfig(source="voxel", normal_frac_bits=12), 12, (0.5, 1.0, 1.0)),
    ],
)
def test_normals_and_magnitude_equal_the_model(cfg, sample_bits, spacing):
    run_case(
        make_case("gradient", cfg=cfg, sample_bits=sample_bits, spacing_zyx=spacing),
        count=60,
        phases=((0.0, 0.0), (0.3, 0.3)),
    )
