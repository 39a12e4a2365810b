"""Trilinear interpolation unit model against float64 trilinear interpolation.

The bound is the module's (``models/units/interp.py``): per axis, the weight's
quantisation error times the cell's largest voxel difference plus one lerp rounding,
three axes; directed roundings (floor, truncate) err by a whole step where nearest ones
err by half.  The reference here is the textbook weighted sum of the eight corners.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.numerics import ROUNDINGS
from models.units import interp as iu

pytestmark = pytest.mark.model

CELL = (2, 2, 2)
voxels = st.lists(st.integers(-(1 << 15), (1 << 15) - 1), min_size=8, max_size=8)
fraction = st.floats(0.0, 1.0, allow_nan=False)
configs = st.builds(
    iu.InterpConfig,
    weight_bits=st.integers(1, 16),
    sample_frac_bits=st.integers(1, 12),
    rounding=st.sampled_from(ROUNDINGS),
)


def float_trilinear(v: np.ndarray, fz: float, fy: float, fx: float) -> float:
    """Corners ``c = 4 dz + 2 dy + dx`` weighted by the products of their fractions."""
    total = 0.0
    for c in range(8):
        dz, dy, dx = (c >> 2) & 1, (c >> 1) & 1, c & 1
        w = (fz if dz else 1 - fz) * (fy if dy else 1 - fy) * (fx if dx else 1 - fx)
        total += w * float(v[c])
    return total


def fixed_at(v: np.ndarray, zyx: tuple[float, float, float], cfg: iu.InterpConfig) -> float:
    taps = iu.interp_taps(np.array([zyx]), CELL, cfg)
    raw = iu.interpolate(np.asarray(v, dtype=np.int64), taps, cfg)
    return float(raw[0]) / (1 << cfg.sample_frac_bits)


@settings(max_examples=400, deadline=None)
@given(voxels, fraction, fraction, fraction, configs)
def test_within_the_documented_bound(v, fz, fy, fx, cfg):
    v = np.array(v)
    spread = float(v.max() - v.min())
    got = fixed_at(v, (fz, fy, fx), cfg)
    assert abs(got - float_trilinear(v, fz, fy, fx)) <= iu.error_bound(spread, cfg)


@settings(max_examples=200, deadline=None)
@given(voxels, fraction, fraction, fraction, configs)
def test_a_sample_never_leaves_its_cell_range(v, fz, fy, fx, cfg):
    """Every lerp is convex in integers (its rounded step lies between 0 and ``b - a``)."""
    v = np.array(v)
    got = fixed_at(v, (fz, fy, fx), cfg)
    assert v.min() <= got <= v.max()


@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_corners_are_exact_in_every_rounding(rounding):
    cfg = iu.InterpConfig(rounding=rounding)
    v = np.array([3, -70, 4095, 12, 0, 999, -4096, 77])
    for c in range(8):
        zyx = (float((c >> 2) & 1), float((c >> 1) & 1), float(c & 1))
        assert fixed_at(v, zyx, cfg) == v[c]


def test_directed_roundings_get_the_wider_bound():
    nearest = iu.InterpConfig(rounding="nearest-even")
    floor = iu.InterpConfig(rounding="floor")
    assert iu.error_bound(100.0, floor) == pytest.approx(2 * iu.error_bound(100.0, nearest))
    # and the floor bound is needed: a whole step is lost at a fraction just under 1
    v = np.array([0, 4095, 0, 4095, 0, 4095, 0, 4095])
    cfg = iu.InterpConfig(weight_bits=4, sample_frac_bits=1, rounding="floor")
    err = abs(fixed_at(v, (0.0, 0.0, 0.999), cfg) - float_trilinear(v, 0.0, 0.0, 0.999))
    assert iu.error_bound(4095.0, nearest) < err <= iu.error_bound(4095.0, cfg)


def test_bilinear_is_trilinear_on_a_voxel_slice(rng):
    cfg = iu.InterpConfig()
    vol = rng.integers(0, 4096, (3, 5, 6))
    promoted = iu.promote(vol.ravel(), cfg)
    for _ in range(50):
        z, y, x = int(rng.integers(0, 3)), rng.uniform(0, 4), rng.uniform(0, 5)
        taps = iu.interp_taps(np.array([[z, y, x]], dtype=np.float64), vol.shape, cfg)
        want = iu.interpolate(promoted, taps, cfg, promoted=True)[0]
        (a0, b0), (fa, fb) = taps.cells[1:, 0], taps.frac[1:, 0]
        corner = [int(promoted[(z * 5 + a0 + i) * 6 + b0 + j]) for i in (0, 1) for j in (0, 1)]
        assert iu.bilinear(*corner, fa, fb, cfg) == want


def test_non_finite_positions_are_refused():
    cfg = iu.InterpConfig()
    for bad in (np.nan, np.inf):
        with pytest.raises(ValueError, match="NaN or Inf"):
            iu.interp_taps(np.array([[0.5, bad, 0.5]]), CELL, cfg)


def test_widths_out_of_range_are_refused():
    with pytest.raises(ValueError, match="weight_bits 1..16"):
        iu.InterpConfig(weight_bits=17)
    with pytest.raises(ValueError, match="sample_frac_bits 1..12"):
        iu.InterpConfig(sample_frac_bits=0)
