"""Embedded-geometry unit (models/units/depth.py): 24-bit depth, tests, colour, blend."""

from __future__ import annotations

import operator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.golden.geometry import GeometryBuffers, blend_behind
from models.units import composite as cu
from models.units import depth as du

pytestmark = pytest.mark.model

#: The reference comparisons: Python's own operators, by the scene's test names.
OPS = dict(
    zip(
        ("<", "<=", "==", ">=", ">", "!="),
        (operator.lt, operator.le, operator.eq, operator.ge, operator.gt, operator.ne),
        strict=True,
    )
)


def test_depth_quantisation_extremes_and_clamping():
    got = du.quantise_depth(np.array([0.0, 1.0, -0.5, 2.0, 0.5, 2.0**-24, 2.0**-23]))
    assert got.tolist() == [0, 0xFFFFFF, 0, 0xFFFFFF, 0x800000, 1, 2]
    assert du.DEPTH.name == "depth.z" and du.FAR == 0xFFFFFF


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_depth_quantisation_is_monotone_and_within_half_an_lsb(a, b):
    qa, qb = du.quantise_depth(np.array([a, b]))
    assert abs(qa / du.FAR - a) <= 0.5 / du.FAR + 1e-15
    if a <= b:
        assert qa <= qb


@pytest.mark.parametrize("test", list(OPS))
def test_every_depth_test_against_the_python_operator(test):
    s, p = np.meshgrid([0, 1, 0x7FFFFF, 0xFFFFFE, 0xFFFFFF], [0, 1, 0x7FFFFF, 0xFFFFFF])
    got = du.passes(test, s.ravel(), p.ravel())
    want = [OPS[test](int(x), int(y)) for x, y in zip(s.ravel(), p.ravel(), strict=True)]
    assert got.tolist() == want


def test_colour_buffer_keeps_zero_and_full_scale_exact():
    rgb, alpha = du.quantise_color(np.array([[0.0, 1.0, 0.5, 1.0], [0.0, 0.0, 0.0, 0.0]]))
    assert rgb.tolist() == [[0, 4096, 2049], [0, 0, 0]]  # 0.5 -> 2048/4095 -> 2048.5 -> up
    assert alpha.tolist() == [4096, 0]


def test_blend_behind_matches_float_and_leaves_opaque_pixels_unchanged():
    cfg = cu.CompositeConfig(output_bits=12)
    one = 1 << cfg.acc_frac_bits
    acc = np.array([[0, 0, 0, 0], [one // 2, one // 4, 0, one], [one // 8, 0, 0, one // 4]])
    rgba = np.array([[0.2, 0.4, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0], [0.0, 1.0, 0.0, 1.0]])
    buffers = du.DepthBuffers(GeometryBuffers(rgba, np.zeros(3)))
    fixed = acc.copy()
    du.blend(fixed, buffers, cfg)
    # Empty ray: the geometry colour exactly (to the colour buffer's 12 bits).
    out = cu.output_to_float(cu.to_output(fixed, cfg), cfg)
    assert np.allclose(out[0], rgba[0], atol=1.0 / 4095)
    # Opaque ray: unchanged to the bit.
    assert fixed[1].tolist() == acc[1].tolist()
    golden = acc / one
    blend_behind(golden, rgba)
    assert np.abs(fixed / one - golden).max() <= 2.0**-12


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(list(OPS)), st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_quantised_test_agrees_with_the_float_test_unless_within_one_lsb(test, s, p):
    fixed = bool(
        du.passes(test, du.quantise_depth(np.array([s])), du.quantise_depth(np.array([p])))[0]
    )
    if abs(s - p) > 1.0 / du.FAR:
        assert fixed == OPS[test](s, p)
