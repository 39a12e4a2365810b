"""Fixed-point formats: rounding modes, saturation, no silent wrap, no NaN."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.numerics import (
    ROUNDINGS,
    SATURATIONS,
    FixedFormat,
    OverflowError_,
    mul,
    psnr,
    rescale,
    rmse,
    round_shift,
)

pytestmark = pytest.mark.model

REFERENCE = {
    "nearest-up": lambda x: np.floor(x + 0.5),
    "nearest-even": np.round,
    "truncate": np.trunc,
    "floor": np.floor,
}


def fmt(signed=False, i=4, f=8, rounding="nearest-up", overflow="saturate") -> FixedFormat:
    return FixedFormat(
        name="t", signed=signed, int_bits=i, frac_bits=f, rounding=rounding, overflow=overflow
    )


def test_ranges_and_description():
    u = fmt(i=0, f=12)
    assert (u.raw_min, u.raw_max, u.width) == (0, 4095, 12)
    s = fmt(signed=True, i=3, f=4)
    assert (s.raw_min, s.raw_max, s.width, s.min_value) == (-128, 127, 8, -8.0)
    assert s.describe() == "s3.4 nearest-up saturate"


@settings(max_examples=300, deadline=None)
@given(
    x=st.floats(-20, 20, allow_nan=False),
    rounding=st.sampled_from(ROUNDINGS),
    frac=st.integers(0, 12),
)
def test_quantize_error_is_bounded_by_the_rounding_mode(x, rounding, frac):
    f = fmt(signed=True, i=6, f=frac, rounding=rounding)
    raw = f.quantize(np.array([x]))[0]
    err = abs(f.to_float(raw) - x)
    bound = f.lsb / 2 if rounding.startswith("nearest") else f.lsb
    assert err <= bound + 1e-12
    assert raw == REFERENCE[rounding](x * 2.0**frac)


@settings(max_examples=300, deadline=None)
@given(
    raw=st.integers(-(1 << 40), 1 << 40),
    shift=st.integers(-4, 20),
    rounding=st.sampled_from(ROUNDINGS),
)
def test_round_shift_matches_exact_rational_rounding(raw, shift, rounding):
    got = int(round_shift(np.array([raw]), shift, rounding)[0])
    if shift <= 0:
        assert got == raw * (1 << -shift)
        return
    import math
    from fractions import Fraction

    q = Fraction(raw, 1 << shift)
    expected = {
        "floor": math.floor(q),
        "truncate": math.trunc(q),
        "nearest-up": math.floor(q + Fraction(1, 2)),
        "nearest-even": round(q),
    }[rounding]
    assert got == expected


def test_saturation_clamps_and_is_counted_never_wraps():
    f = fmt(i=0, f=8)
    before = SATURATIONS["t"]
    raw = f.quantize(np.array([-0.5, 0.25, 1.5, 300.0]))
    np.testing.assert_array_equal(raw, [0, 64, 255, 255])
    assert SATURATIONS["t"] - before == 3


def test_error_overflow_raises_with_the_format_named():
    f = fmt(i=2, f=2, overflow="error")
    with pytest.raises(OverflowError_, match=r"t \(u2\.2"):
        f.quantize(np.array([4.0]))


def test_nan_and_inf_are_refused():
    with pytest.raises(ValueError, match="NaN"):
        fmt().quantize(np.array([np.nan]))
    with pytest.raises(ValueError, match="NaN or Inf"):
        fmt().quantize(np.array([np.inf]))


def test_rescale_and_mul_are_exact_then_rounded_once():
    a_f, b_f = fmt(i=4, f=8), fmt(i=0, f=9)
    out = fmt(i=4, f=4)
    a = a_f.quantize(np.array([3.30078125]))  # exactly representable in u4.8
    b = b_f.quantize(np.array([0.5]))
    np.testing.assert_array_equal(mul(a, a_f, b, b_f, out), out.quantize(np.array([1.650390625])))
    np.testing.assert_array_equal(rescale(a, a_f, out), [53])  # 3.30078125 * 16 = 52.8 -> 53


def test_metrics():
    a = np.zeros((4, 4))
    b = np.full((4, 4), 0.1)
    assert rmse(a, b) == pytest.approx(0.1)
    assert psnr(a, b) == pytest.approx(20.0)
    assert psnr(a, a) == float("inf")
