"""Combiner ALUs (models/units/combine.py) against integer and float references.

Every opcode at the extremes (0, full scale, saturation), the documented bounds as
properties, the tree wiring, and the float64 counterparts (hwsim/golden/classification.py)
within the documented rounding of the fixed-point ones.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.golden.classification import float_alu
from hwsim.spec.scene_features import LEAF_OPCODES
from models.units import combine

pytestmark = pytest.mark.model

F8, F12 = 255, 4095


#: Plain-Python integer reference of each non-multiplying opcode (from the docstring).
REFERENCE = {
    "a": lambda a, b, full: a,
    "b": lambda a, b, full: b,
    "and": lambda a, b, full: a & b,
    "or": lambda a, b, full: a | b,
    "xor": lambda a, b, full: a ^ b,
    "add": lambda a, b, full: min(a + b, full),
    "sub": lambda a, b, full: max(a - b, 0),
    "rsub": lambda a, b, full: max(b - a, 0),
    "min": lambda a, b, full: min(a, b),
    "max": lambda a, b, full: max(a, b),
}


def ref(op: str, a: int, b: int, full: int) -> int:
    """One opcode on plain Python integers; ``mulK``: ``K round(a b / full)``, clamped."""
    if op in REFERENCE:
        return REFERENCE[op](a, b, full)
    k = {"mul": 1, "mul2": 2, "mul4": 4, "mul8": 8}[op]
    q, r = divmod(a * b, full)
    p = q + (1 if 2 * r >= full else 0)  # round half up, exact
    return min(k * p, full)


EXTREMES = [0, 1, 127, 128, 254, 255]


@pytest.mark.parametrize("op", LEAF_OPCODES)
def test_every_leaf_opcode_matches_the_integer_reference_at_the_8_bit_extremes(op):
    a, b = np.meshgrid(EXTREMES, EXTREMES)
    got = combine.alu(op, a.ravel(), b.ravel(), 8)
    want = [ref(op, int(x), int(y), F8) for x, y in zip(a.ravel(), b.ravel(), strict=True)]
    assert got.tolist() == want


@pytest.mark.parametrize("op", LEAF_OPCODES)
def test_every_leaf_opcode_matches_the_integer_reference_exhaustively_on_8_bits(op):
    a, b = (g.ravel() for g in np.meshgrid(np.arange(256), np.arange(256)))
    got = combine.alu(op, a, b, 8)
    want = [ref(op, int(x), int(y), F8) for x, y in zip(a, b, strict=True)]
    assert got.tolist() == want


def test_saturation_points_of_the_clamped_ops():
    assert combine.alu("add", [F12, 4000, 95], [1, 96, 4000], 12).tolist() == [F12, F12, F12]
    assert combine.alu("sub", [0, 5, F12], [1, 6, F12], 12).tolist() == [0, 0, 0]
    assert combine.alu("rsub", [F12], [0], 12).tolist() == [0]
    # x8 product of 1/2 * 1/2 = 2.0 saturates; 1/8 * 1/8 * 8 = 1/8 does not.
    half, eighth = 2048, 512
    assert combine.alu("mul8", [half], [half], 12).tolist() == [F12]
    assert combine.alu("mul8", [eighth], [eighth], 12).tolist() == [
        ref("mul8", eighth, eighth, F12)
    ]
    assert ref("mul8", eighth, eighth, F12) < F12
    # Full scale is the identity of the products, 0 their zero.
    assert combine.alu("mul", [F12, 0, 1234], [1234, F12, F12], 12).tolist() == [1234, 0, 1234]


def test_unknown_opcode_is_refused():
    with pytest.raises(ValueError, match="unknown combiner opcode"):
        combine.alu("nand", [1], [2], 8)


@settings(max_examples=300, deadline=None)
@given(
    st.sampled_from(LEAF_OPCODES),
    st.integers(0, F12),
    st.integers(0, F12),
)
def test_results_stay_in_range_and_match_the_float_op_within_the_documented_bound(op, a, b):
    got = int(combine.alu(op, np.array([a]), np.array([b]), 12)[0])
    assert 0 <= got <= F12
    assert got == ref(op, a, b, F12)
    real = float(float_alu(op, np.array([a / F12]), np.array([b / F12]), 12)[0])
    k = {"mul": 1, "mul2": 2, "mul4": 4, "mul8": 8}.get(op, 0)
    bound = (k / 2 if k else 0) / F12 + 1e-12  # docstring: k/2 LSB for products, exact else
    assert abs(got / F12 - real) <= bound


@settings(max_examples=200, deadline=None)
@given(st.integers(0, F12), st.integers(0, F12))
def test_unorm_product_is_the_correctly_rounded_quotient(a, b):
    p = int(combine.product(np.array([a]), np.array([b]), F12)[0])
    # p - 1/2 <= a b / F < p + 1/2 (round half up), in exact integers.
    assert (2 * p - 1) * F12 <= 2 * a * b < (2 * p + 1) * F12


def rgba(rgb, alpha):
    return combine.Rgba(np.array([rgb], dtype=np.int64), np.array([alpha], dtype=np.int64))


def test_tree_wiring_leaf0_leaf1_final():
    l0, l1 = rgba([10, 20, 30], 100), rgba([1, 2, 3], 4000)
    l2, l3 = rgba([200, 0, 0], 50), rgba([100, 100, 100], 60)
    out = combine.combine_tree([l0, l1, l2, l3], ("add", "max"), ("sub", "add"), ("max", "min"))
    left = ([11, 22, 33], 4000)
    right = ([100, 0, 0], 110)
    assert out.rgb.tolist() == [[max(x, y) for x, y in zip(left[0], right[0], strict=True)]]
    assert out.alpha.tolist() == [min(left[1], right[1])]


def test_one_lut_bypasses_the_alus_and_missing_inputs_read_zero():
    l0 = rgba([10, 20, 30], 100)
    same = combine.combine_tree([l0], ("b", "b"), ("b", "b"), ("b", "b"))
    assert same.rgb.tolist() == [[10, 20, 30]] and same.alpha.tolist() == [100]
    # Three LUTs: lut3 is zero, so leaf1 = "b" passes zeros; final "a" keeps leaf0.
    l2 = rgba([7, 7, 7], 7)
    out = combine.combine_tree([l0, l0, l2], ("add", "add"), ("b", "b"), ("add", "add"))
    assert out.rgb.tolist() == [[20, 40, 60]] and out.alpha.tolist() == [200]


def test_final_only_mul_b_alpha_weights_every_channel_by_the_other_opacity():
    a = rgba([255, 128, 0], F12)
    mask_on, mask_off, half = rgba([0, 0, 0], F12), rgba([0, 0, 0], 0), rgba([0, 0, 0], 2048)
    for mask, want_rgb, want_a in (
        (mask_on, [255, 128, 0], F12),
        (mask_off, [0, 0, 0], 0),
        (half, [128, 64, 0], 2048),
    ):
        out = combine.combine_tree(
            [a, a, mask, mask], ("a", "a"), ("a", "a"), ("mul_b_alpha", "mul_b_alpha")
        )
        assert out.rgb.tolist() == [want_rgb] and out.alpha.tolist() == [want_a]


def test_logic_ops_in_float_quantise_to_the_stored_width():
    got = float_alu("xor", np.array([1.0, 0.5]), np.array([0.0, 0.5]), 8)
    assert got.tolist() == [1.0, 0.0]
    got = float_alu("or", np.array([128 / 255]), np.array([1 / 255]), 8)
    assert got.tolist() == [129 / 255]
