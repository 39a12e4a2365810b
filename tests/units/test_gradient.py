"""Gradient unit model: central differences, exact integer helpers, unit normals.

References are independent of the unit's code: ``numpy.gradient`` for the voxel
differences, the interpolation unit at explicitly moved positions for the sample
differences, Python's exact integers for the square root and divisions, and float64
``-g / |g|`` for the normals (bound from ``models/units/gradient.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from models.units import gradient as gu
from models.units import interp as iu

pytestmark = pytest.mark.model

#: The unit's domain (normals' docstring): a 30-bit signed difference, the widest any
#: datapath makes (16 voxel bits, 12 fraction bits, a difference of two).
component = st.integers(-(1 << 30) + 1, (1 << 30) - 1)


def test_voxel_differences_are_twice_numpys_gradient(rng):
    raw = rng.integers(0, 4096, (5, 7, 6))
    dx, dy, dz = gu.voxel_differences(raw)
    for axis, got in ((2, dx), (1, dy), (0, dz)):
        want = 2 * np.gradient(raw.astype(np.float64), axis=axis)  # one-sided at the faces
        np.testing.assert_array_equal(got, want.ravel())


def test_a_one_voxel_axis_has_no_difference(rng):
    raw = rng.integers(0, 4096, (1, 4, 5))
    dx, dy, dz = gu.voxel_differences(raw)
    assert not dz.any() and dx.any() and dy.any()


def test_wide_voxels_take_int64_and_stay_exact():
    raw = np.array([[[0, 1 << 40, 0]]], dtype=np.int64)
    dx, _, _ = gu.voxel_differences(raw)
    assert dx.dtype == np.int64 and list(dx) == [2 << 40, 0, -(2 << 40)]


def test_sample_differences_are_the_interpolated_neighbours(rng):
    cfg = iu.InterpConfig()
    shape = (6, 7, 8)
    flat = rng.integers(0, 4096, shape).ravel()
    zyx = rng.uniform(0, 1, (300, 3)) * (np.array(shape) - 1)
    got = gu.sample_differences(flat, zyx, shape, cfg)
    for axis_xyz in range(3):
        e = np.zeros(3)
        e[2 - axis_xyz] = 1.0  # positions are (z, y, x)
        ahead = iu.interpolate(flat, iu.interp_taps(zyx + e, shape, cfg), cfg)
        behind = iu.interpolate(flat, iu.interp_taps(zyx - e, shape, cfg), cfg)
        np.testing.assert_array_equal(got[:, axis_xyz], ahead - behind)


@settings(max_examples=500, deadline=None)
@given(st.integers(0, (1 << 62) - 1))  # its domain: three 30-bit squares stay below
def test_isqrt_is_exact(s):
    assert int(gu.isqrt_raw(np.int64(s))) == math.isqrt(s)


@pytest.mark.parametrize("k", [1, 2, 3, 1 << 20, (1 << 30) - 1, (1 << 31) - 1])
def test_isqrt_at_perfect_squares_and_their_neighbours(k):
    for s in (k * k - 1, k * k, k * k + 1):
        assert int(gu.isqrt_raw(np.int64(s))) == math.isqrt(s)


@settings(max_examples=300, deadline=None)
@given(st.integers(0, (1 << 63) - 1))
def test_bit_length_is_exact(m):
    assert int(gu.bit_length_raw(np.int64(m))) == m.bit_length()


@settings(max_examples=300, deadline=None)
@given(st.integers(-(1 << 52), 1 << 52), st.integers(1, 1 << 30))
def test_floor_division_is_exact_for_the_quotients_it_serves(n, d):
    assume(abs(n // d) < 1 << 50)
    assert int(gu.floor_div_raw(np.int64(n), np.int64(d))) == n // d


@settings(max_examples=500, deadline=None)
@given(component, component, component, st.integers(2, 20))
def test_normals_within_the_documented_bound(gx, gy, gz, f):
    assume((gx, gy, gz) != (0, 0, 0))
    cfg = gu.GradientConfig(normal_frac_bits=f)
    got = gu.normals(np.array([[gx, gy, gz]]), cfg)[0] / (1 << f)
    g = np.array([gx, gy, gz], dtype=np.float64)
    want = -g / np.linalg.norm(g)
    assert np.abs(got - want).max() < 2.0**-f


def test_the_bound_is_needed_where_the_magnitude_truncates_most():
    """The case that broke the bound once documented (``2**-(F+1) + 2**-(F+2)``)."""
    got = gu.normals(np.array([[0, 222, 32768]]), gu.GradientConfig(normal_frac_bits=15))[0]
    want = -np.array([0, 222, 32768]) / np.hypot(222, 32768)
    err = np.abs(got / 2**15 - want).max()
    assert 2.0**-16 + 2.0**-17 < err < 2.0**-15


@settings(max_examples=500, deadline=None)
@given(component, component, component, st.integers(0, 20))
def test_the_float_normal_is_normal_raw(gx, gy, gz, f):
    """normal_float_raw (the compiled stage's normals) gives normal_raw's integers, in
    its float range and beyond it (where it falls back)."""
    g = (np.int64(gx), np.int64(gy), np.int64(gz))
    want = tuple(int(v) for v in gu.normal_raw(*g, f))
    assert tuple(int(v) for v in gu.normal_float_raw(*g, f)) == want


@pytest.mark.parametrize("f", [1, 8, 10, 15, 24])
def test_the_compiled_float_normal_is_normal_raw_on_many_vectors(rng, f):
    """Compiled, over a million vectors of every magnitude up to the float range's edge
    (``|g|**2`` near ``2**52``), zero, the axes and perfect-square magnitudes."""
    import numba

    from models import fused_stage  # noqa: F401  (registers the unit functions)

    @numba.njit
    def both(g, f):
        out = np.empty((2, 3, g.shape[1]), np.int64)
        for j in range(g.shape[1]):
            out[0, :, j] = gu.normal_raw(g[0, j], g[1, j], g[2, j], f)
            out[1, :, j] = gu.normal_float_raw(g[0, j], g[1, j], g[2, j], f)
        return out

    parts = [rng.integers(-hi, hi + 1, (3, 50_000)) for hi in (1, 3, 40, 3000, 1 << 16)]
    parts += [rng.integers(-hi, hi + 1, (3, 50_000)) for hi in (1 << 20, 1 << 25)]
    k = np.arange(1, 1 << 12)
    edges = [np.stack([k * k - 1, k * 0, k * 0]), np.stack([k, 2 * k, 2 * k])]  # |g| = 3k
    edges.append(np.array([[0, 1 << 25, -(1 << 25), 0], [0, 0, 0, 1 << 26], [0, 0, 1, 0]]))
    g = np.concatenate(parts + edges, axis=1).astype(np.int64)
    out = both(g, f)
    assert np.array_equal(out[0], out[1])


def test_the_zero_gradient_gives_the_zero_normal_never_nan():
    n = gu.normals(np.zeros((3, 3), dtype=np.int64), gu.GradientConfig())
    assert n.dtype == np.int64 and not n.any()


def test_magnitude_is_the_exact_floor_root(rng):
    g = rng.integers(-(1 << 20), 1 << 20, (200, 3))
    want = [math.isqrt(int(a) ** 2 + int(b) ** 2 + int(c) ** 2) for a, b, c in g]
    assert list(gu.magnitude(g)) == want


def test_world_scaling_is_a_no_op_on_isotropic_data(rng):
    g = rng.integers(-5000, 5000, (50, 3))
    assert gu.to_world(g, (0.7, 0.7, 0.7), 4, gu.GradientConfig()) is g


def test_world_scaling_of_anisotropic_data_within_its_rounding(rng):
    g = rng.integers(-(1 << 16), 1 << 16, (500, 3))
    spacing_zyx = (2.5, 1.0, 0.7)
    got = gu.to_world(g, spacing_zyx, 4, gu.GradientConfig())
    ratio = min(spacing_zyx) / np.array(spacing_zyx)[::-1]  # per x, y, z
    # the ratio is UQ1.12 (error <= 2**-13 each) and the product rounds to nearest
    assert (np.abs(got - g * ratio) <= np.abs(g) * 2.0**-13 + 0.5).all()


def test_config_out_of_range_is_refused():
    with pytest.raises(ValueError, match="source sample\\|voxel"):
        gu.GradientConfig(source="central")
    with pytest.raises(ValueError, match="normal_frac_bits 2..20"):
        gu.GradientConfig(normal_frac_bits=21)
