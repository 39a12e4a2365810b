"""Voxel conversion unit model: a volume's values into the machine's unsigned voxels.

The three rules of ``models/units/voxel.py``, checked against their own statement:
exact (``value = offset + scale * raw``) for narrow unsigned and fitting signed data,
within half a raw step for the linear map, always inside ``[0, 2**bits - 1]``, and
non-decreasing in the value (block minima and maxima stay bounds).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from hwsim.volumes.volume import Volume
from models.units import voxel as vu

pytestmark = pytest.mark.model

BITS = st.sampled_from([8, 12, 16])


def volume_of(data: np.ndarray, bits: int = 0) -> Volume:
    return Volume(data=data, bits=bits, name="t")


@settings(max_examples=200, deadline=None)
@given(BITS, st.integers(1, 16), st.data())
def test_narrow_unsigned_data_shifts_exactly(bits, data_bits, draw):
    if data_bits > bits:
        data_bits = bits
    dtype = np.uint8 if data_bits <= 8 else np.uint16
    arr = draw.draw(hnp.arrays(dtype, (2, 3, 4), elements=st.integers(0, (1 << data_bits) - 1)))
    raw, vmap = vu.convert_volume(volume_of(arr, data_bits), bits)
    assert (raw == arr.astype(np.int64) << (bits - data_bits)).all()
    np.testing.assert_array_equal(vmap.to_value(raw), arr.astype(np.float64))


@settings(max_examples=200, deadline=None)
@given(BITS, st.data())
def test_signed_data_that_fits_is_offset_exactly(bits, draw):
    lo = draw.draw(st.integers(-30000, 30000))
    span = draw.draw(st.integers(0, (1 << bits) - 1))
    hi = min(lo + span, 32767)
    arr = draw.draw(hnp.arrays(np.int16, (3, 3, 3), elements=st.integers(lo, hi)))
    raw, vmap = vu.convert_volume(volume_of(arr), bits)
    assert raw.min() >= 0 and raw.max() <= (1 << bits) - 1
    np.testing.assert_array_equal(vmap.to_value(raw), arr.astype(np.float64))


@settings(max_examples=200, deadline=None)
@given(
    BITS,
    hnp.arrays(np.float32, (3, 4, 5), elements=st.floats(-1e6, 1e6, allow_nan=False, width=32)),
)
def test_float_data_maps_linearly_within_half_a_step(bits, arr):
    volume = volume_of(arr)
    raw, vmap = vu.convert_volume(volume, bits)
    assert raw.min() >= 0 and raw.max() <= (1 << bits) - 1
    lo, hi = volume.value_range
    if hi > lo:
        assert np.abs(vmap.to_value(raw) - arr).max() <= 0.5 * vmap.scale * (1 + 1e-9)
        assert raw.min() == 0 and raw.max() == (1 << bits) - 1  # the ends are the range's
    else:
        assert not raw.any()  # a constant volume maps to 0


@settings(max_examples=100, deadline=None)
@given(BITS, hnp.arrays(np.int16, (2, 5, 5), elements=st.integers(-32768, 32767)))
def test_every_rule_is_non_decreasing_in_the_value(bits, arr):
    volume = volume_of(arr)
    values = np.sort(arr.ravel())
    raw, _ = vu.convert_values(values, volume, bits)
    assert (np.diff(raw) >= 0).all()


def test_integers_wider_than_the_voxel_take_the_linear_map():
    arr = np.array([[[-20000, 100, 20000]]], dtype=np.int16)  # a span of 40000 > 4095
    raw, vmap = vu.convert_volume(volume_of(arr), 12)
    assert list(raw.ravel()) == [0, 2058, 4095] and vmap.scale == pytest.approx(40000 / 4095)


@settings(max_examples=100, deadline=None)
@given(BITS, hnp.arrays(np.int16, (4, 3, 5), elements=st.integers(-32768, 32767)))
def test_the_volume_is_converted_slice_by_slice_to_uint16_by_the_same_rule(bits, arr):
    """Memory: the machine's raw voxels are uint16 (not an int64 copy of the volume),
    converted a slice at a time; the values are the whole-array rule's."""
    volume = volume_of(arr)
    raw, vmap = vu.convert_volume(volume, bits)
    whole, whole_map = vu.convert_values(arr, volume, bits)
    assert raw.dtype == np.uint16 and np.array_equal(raw, whole) and vmap == whole_map
