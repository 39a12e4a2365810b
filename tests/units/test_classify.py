"""Classification unit model: the LUT against the float transfer function, the read-out
expansion, nearest-entry indexing and gradient-magnitude modulation.

Bounds from ``models/units/classify.py``: half an entry step times the function's largest
slope (index rounding), ``2**-(n+1)`` of ``n``-bit storage and ``2**-13`` of expansion.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.spec.transfer import TransferFunction
from models.units import classify as cu

pytestmark = pytest.mark.model

ONE = 4096


@pytest.mark.parametrize("bits", [1, 4, 8, 12])
def test_expansion_is_exact_at_the_ends_and_within_half_a_step(bits):
    full = (1 << bits) - 1
    u = np.arange(full + 1)
    got = cu.expand(u, bits)
    assert got[0] == 0 and got[-1] == ONE
    assert (np.diff(got) >= 0).all()
    assert np.abs(got / ONE - u / full).max() <= 2.0**-13


@settings(max_examples=400, deadline=None)
@given(
    st.integers(1, 16),
    st.integers(0, 12),
    st.sampled_from([2, 16, 256, 4096, 65536]),
    st.integers(-(1 << 20), 1 << 30),
)
def test_a_sample_indexes_the_nearest_entry(voxel_bits, frac_bits, entries, sample):
    cfg = cu.ClassifyConfig(entries=entries)
    # entry i stands for raw value i 2**B / entries; nearest, halves up, then clamped
    position = sample / 2**frac_bits * entries / 2**voxel_bits
    want = min(max(int(np.floor(position + 0.5)), 0), entries - 1)
    assert int(cu.lut_index(np.array([sample]), voxel_bits, frac_bits, cfg)[0]) == want


@pytest.mark.parametrize(("entries", "color_bits", "alpha_bits"), [(4096, 8, 12), (256, 8, 8)])
def test_classified_samples_within_the_documented_bound(rng, entries, color_bits, alpha_bits):
    """A ramp with known slopes, sampled between entries: the error is index rounding
    (half an entry step times the slope) plus storage and expansion."""
    values = np.array([0.0, 1000.0, 2500.0, 4095.0])
    rgba = np.array([[0, 0, 0, 0], [1, 0.5, 0.2, 0.3], [0.2, 1, 0.6, 0.9], [1, 1, 1, 1]])
    tf = TransferFunction(values=values, rgba=rgba)
    cfg = cu.ClassifyConfig(entries=entries, color_bits=color_bits, alpha_bits=alpha_bits)
    voxel_bits, frac_bits = 12, 4
    lut = cu.build_lut(tf, lambda raw: raw, voxel_bits, cfg)
    samples = rng.integers(0, (1 << (voxel_bits + frac_bits)) - 1, 5000)
    rgb, alpha = cu.classify(samples, lut, voxel_bits, frac_bits, cfg)
    want = tf.classify(samples / 2**frac_bits)
    slope = np.abs(np.diff(rgba, axis=0) / np.diff(values)[:, None]).max(axis=0)
    half_entry = 0.5 * 2**voxel_bits / entries
    for got, channel, bits in ((rgb, slice(0, 3), color_bits), (alpha, 3, alpha_bits)):
        bound = half_entry * slope[channel] + 2.0 ** -(bits + 1) + 2.0**-13
        assert (np.abs(got / ONE - want[:, channel]) <= bound).all()


def test_pre_classification_reads_the_entry_of_each_voxel(rng):
    cfg = cu.ClassifyConfig(entries=256)
    tf = TransferFunction(
        values=np.array([0.0, 4095.0]), rgba=np.array([[0, 0, 0, 0], [1, 1, 1, 1.0]])
    )
    lut = cu.build_lut(tf, lambda raw: raw, 12, cfg)
    raw = rng.integers(0, 4096, (3, 4, 5))
    r, g, b, a = cu.classify_voxels(raw, lut, 12, cfg)
    i = np.minimum((raw.ravel() + 8) // 16, 255)  # nearest of 256 entries 16 apart
    assert (a == lut.alpha12[i]).all() and (r == lut.rgb12[i, 0]).all()
    assert (g == lut.rgb12[i, 1]).all() and (b == lut.rgb12[i, 2]).all()


@settings(max_examples=300, deadline=None)
@given(st.integers(0, ONE), st.integers(0, ONE))
def test_modulation_is_the_rounded_product(alpha, factor):
    got = int(cu.modulate(np.array([alpha]), np.array([0]), np.array([factor]))[0])
    assert got == (alpha * factor + ONE // 2) // ONE  # halves up
    assert got <= alpha


def test_modulation_by_one_and_by_zero_is_exact(rng):
    alpha = rng.integers(0, ONE + 1, 100)
    table = np.array([0, ONE])
    assert (cu.modulate(alpha, np.ones(100, dtype=np.int64), table) == alpha).all()
    assert not cu.modulate(alpha, np.zeros(100, dtype=np.int64), table).any()


def test_gradient_magnitude_indexes_its_nearest_table_entry():
    cfg = cu.ClassifyConfig(gm_entries=64)
    units_per_magnitude, max_magnitude = 0.01, 50.0  # integer units -> value/world units
    scale = cu.gm_scale(units_per_magnitude, max_magnitude, cfg)
    m = np.arange(0, 6000, 7)
    got = cu.gm_index(m, scale, cfg)
    exact = m * units_per_magnitude * (cfg.gm_entries - 1) / max_magnitude
    want = np.minimum(np.floor(exact + 0.5), cfg.gm_entries - 1)
    # the scale is UQ0.24: an index can move only where the exact one is within a hair
    # of a half
    near_half = np.abs(exact - np.floor(exact) - 0.5) < m * 2.0**-24 + 1e-12
    assert (got[~near_half] == want[~near_half]).all()
    assert got.max() == cfg.gm_entries - 1 and got.min() == 0


def test_a_table_with_no_magnitudes_indexes_entry_zero():
    cfg = cu.ClassifyConfig()
    assert cu.gm_scale(1.0, 0.0, cfg) == 0
    assert not cu.gm_index(np.array([0, 10**6]), 0, cfg).any()


def test_geometry_out_of_range_is_refused():
    with pytest.raises(ValueError, match="power of two"):
        cu.ClassifyConfig(entries=1000)
    with pytest.raises(ValueError, match="1..12"):
        cu.ClassifyConfig(alpha_bits=13)
    with pytest.raises(ValueError, match="gm_entries: 2..4096"):
        cu.ClassifyConfig(gm_entries=1)
