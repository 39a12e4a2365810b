"""hwsim.core.models: the one translator from a schema mismatch to the house's error line.

Every file kind's model is built from these types; the fuzz tier (tests/fuzz) drives the
real models, these tests pin the wording and the key paths of each kind of mismatch.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import msgspec
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hwsim.core.errors import InputError
from hwsim.core.models import Finite, Schema, between, count, integer, validate


class Inner(Schema):
    bits: integer(1, 64) = 8
    kind: Literal["a", "b"] = "a"
    scale: between(0, 10, open_lo=True) = msgspec.field(name="scale-x", default=1.0)
    size: tuple[count(), count(), count()] = (1, 1, 1)


class Doc(Schema):
    inner: Inner
    values: list[integer(0)] = []
    named: dict[str, Inner] = {}
    weights: dict[str, Finite] = {}


def error(doc) -> str:
    with pytest.raises(InputError) as info:
        validate(doc, Doc, "f.toml")
    return str(info.value)


@pytest.mark.parametrize(
    ("doc", "line"),
    [
        ({"inner": 7}, "f.toml: inner: must be a table, got 7"),
        (
            {"inner": {"bits": "x"}},
            "f.toml: inner.bits: must be an integer, got 'x' (allowed: 1 .. 64)",
        ),
        (
            {"inner": {"bits": True}},
            "f.toml: inner.bits: must be an integer, got true (allowed: 1 .. 64)",
        ),
        ({"inner": {"bits": 0}}, "f.toml: inner.bits: out of range, got 0 (allowed: 1 .. 64)"),
        ({"inner": {"kind": "c"}}, "f.toml: inner.kind: unknown value 'c' (allowed: a, b)"),
        ({}, "f.toml: inner: is required"),
        ({"inner": {"size": [1, 2]}}, "f.toml: inner.size: must be an array of length 3, got 2"),
        (
            {"inner": {}, "values": [1, "a"]},
            "f.toml: values[1]: must be an integer, got 'a' (allowed: >= 0)",
        ),
        (
            {"inner": {"bitz": 1}},
            "f.toml: inner.bitz: unknown key 'bitz' (allowed: bits, kind, scale-x, size)",
        ),
        (
            {"inner": {}, "named": {"z": {"bits": -1}}},
            "f.toml: named.z.bits: out of range, got -1 (allowed: 1 .. 64)",
        ),
        ([1, 2], "f.toml: <top>: must be a table, got [1, 2]"),
    ],
)
def test_each_mismatch_is_one_line_naming_file_key_and_allowed(doc, line):
    assert error(doc) == line


@given(st.sampled_from([math.nan, math.inf, -math.inf]))
def test_floats_are_finite(value):
    assert "scale-x: out of range" in error({"inner": {"scale-x": value}})
    assert "weights.w: out of range" in error({"inner": {}, "weights": {"w": value}})


def test_a_valid_document_converts_with_defaults_and_widened_ints():
    doc = validate({"inner": {"scale-x": 3, "size": [2, 3, 4]}}, Doc, "f.toml")
    assert doc.inner.scale == 3.0 and isinstance(doc.inner.scale, float)
    assert doc.inner.size == (2, 3, 4) and doc.inner.bits == 8


def test_prefix_places_a_sub_document_in_its_file():
    with pytest.raises(InputError, match=r"^f.toml: memory.inner.bits: must be an integer"):
        validate({"inner": {"bits": "x"}}, Doc, "f.toml", prefix="memory")


def test_a_string_off_its_pattern_names_the_pattern():
    class Named(Schema):
        family: Annotated[str, msgspec.Meta(pattern=r"^[a-z]+$")] = "a"

    with pytest.raises(InputError) as info:
        validate({"family": "Bad"}, Named, "f.toml")
    assert str(info.value) == "f.toml: family: invalid 'Bad' (allowed: matching ^[a-z]+$)"


class Op(Schema):
    rgb: Literal["zz", "a", "m"] = "a"


class Choices(Schema):
    """Choices in a union with a table, absent keys (UNSET) and bounded lists."""

    op: Literal["zz", "a", "m"] | Op | msgspec.UnsetType = msgspec.UNSET
    mode: Literal["zz", "a"] | msgspec.UnsetType = msgspec.UNSET
    inner: Inner | msgspec.UnsetType = msgspec.UNSET
    luts: Annotated[list[int], msgspec.Meta(min_length=1, max_length=4)] = []


@pytest.mark.parametrize(
    ("doc", "line"),
    [
        ({"op": "b"}, "f.toml: op: unknown value 'b' (allowed: zz, a, m)"),
        ({"op": 3}, "f.toml: op: must be a string or a table, got 3 (allowed: zz, a, m)"),
        ({"op": {"rgb": "b"}}, "f.toml: op.rgb: unknown value 'b' (allowed: zz, a, m)"),
        ({"mode": 1}, "f.toml: mode: must be a string, got 1 (allowed: zz, a)"),
        ({"inner": {"bits": 0}}, "f.toml: inner.bits: out of range, got 0 (allowed: 1 .. 64)"),
        ({"luts": []}, "f.toml: luts: must be an array of length >= 1 (allowed: length 1 .. 4)"),
    ],
)
def test_choices_keep_their_order_and_unset_keys_are_followed(doc, line):
    with pytest.raises(InputError) as info:
        validate(doc, Choices, "f.toml")
    assert str(info.value) == line


class Sizes(Schema):
    """A value that is N or [W, H] (a list: msgspec 0.22 misreports the length of a tuple in
    a union with a constrained int, and may crash)."""

    image: list[
        count(4096) | Annotated[list[count(4096)], msgspec.Meta(min_length=2, max_length=2)]
    ]


@pytest.mark.parametrize(
    ("doc", "line"),
    [
        ({"image": [0]}, "f.toml: image[0]: out of range, got 0 (allowed: 1 .. 4096)"),
        ({"image": [[16, 0]]}, "f.toml: image[0][1]: out of range, got 0 (allowed: 1 .. 4096)"),
        (
            {"image": [[16, 16, 16]]},
            "f.toml: image[0]: must be an array of length <= 2 (allowed: length 2 .. 2)",
        ),
    ],
)
def test_a_union_member_out_of_range_says_what_it_allows(doc, line):
    with pytest.raises(InputError) as info:
        validate(doc, Sizes, "f.toml")
    assert str(info.value) == line
