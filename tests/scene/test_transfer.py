"""Transfer functions: piecewise-linear classification, presets, raw tables."""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.spec.scene import TransferSpec
from hwsim.spec.transfer import TransferFunction, preset_points, resolve_transfer
from hwsim.volumes.volume import Volume


def volume(data, **kw) -> Volume:
    return Volume(data=np.asarray(data), **kw)


def test_classify_is_piecewise_linear_and_clamped():
    tf = TransferFunction(
        values=np.array([0.0, 10.0]), rgba=np.array([[0, 0, 0, 0], [1, 0.5, 0.25, 1.0]])
    )
    out = tf.classify(np.array([-5.0, 0.0, 2.5, 10.0, 99.0]))
    assert out.shape == (5, 4)
    np.testing.assert_allclose(out[:, 3], [0, 0, 0.25, 1, 1])
    np.testing.assert_allclose(out[2, :3], [0.25, 0.125, 0.0625])
    np.testing.assert_allclose(tf.opacity(np.array([5.0])), [0.5])
    np.testing.assert_array_equal(tf.gradient_factor(np.array([3.0, 7.0])), [1.0, 1.0])


def test_visible_range_bounds_the_nonzero_opacity():
    tf = TransferFunction(
        values=np.array([0, 10, 20, 30.0]),
        rgba=np.array([[0, 0, 0, 0], [1, 1, 1, 0], [1, 1, 1, 1], [1, 1, 1, 0]]),
    )
    assert tf.visible_range() == (10.0, 30.0)
    empty = TransferFunction(values=np.array([0, 1.0]), rgba=np.zeros((2, 4)))
    assert empty.visible_range() is None


def test_gradient_modulation_multiplies_by_the_table():
    tf = resolve_transfer(
        TransferSpec(preset="ramp", gradient_opacity=((0, 0.0), (10, 1.0))),
        volume(np.zeros((2, 2, 2), np.uint8) + np.arange(2, dtype=np.uint8)),
    )
    np.testing.assert_allclose(tf.gradient_factor(np.array([0, 5, 20.0])), [0, 0.5, 1])


def test_ct_preset_hides_air_and_shows_bone():
    ct = volume(np.full((2, 2, 2), -1000, np.int16), units="HU")
    tf = resolve_transfer(TransferSpec(preset="auto"), ct)
    air, soft, bone = tf.classify(np.array([-1000.0, 40.0, 1000.0]))
    assert air[3] == 0.0
    assert 0 < soft[3] < 0.1
    assert bone[3] > 0.5 and bone[:3].min() > 0.85  # warm white


@pytest.mark.parametrize("preset", ["auto", "ct", "mr", "ramp"])
def test_presets_are_valid_for_constant_volumes(preset):
    constant = volume(np.full((3, 3, 3), 7, np.uint8))
    pts = preset_points(preset, constant)
    tf = TransferFunction(values=pts[:, 0], rgba=pts[:, 1:])
    assert np.isfinite(tf.classify(np.array([0.0, 7.0, 255.0]))).all()


def test_raw_table_spans_the_voxel_type_by_default(tmp_path):
    table = np.zeros((256, 4))
    table[:, 3] = np.linspace(0, 1, 256)
    path = tmp_path / "tf.npy"
    np.save(path, table)
    tf = resolve_transfer(
        TransferSpec(preset=None, table=str(path)), volume(np.zeros((2, 2, 2), np.uint8))
    )
    np.testing.assert_allclose(tf.opacity(np.array([0.0, 255.0, 127.5])), [0, 1, 0.5])


def test_raw_table_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.npy"
    np.save(bad, np.full((4, 3), 0.5))
    vol = volume(np.zeros((2, 2, 2), np.uint8))
    with pytest.raises(InputError, match=r"bad\.npy: transfer\.table: table shape"):
        resolve_transfer(TransferSpec(preset=None, table=str(bad)), vol)
    nan = tmp_path / "nan.npy"
    np.save(nan, np.full((4, 4), np.nan))
    with pytest.raises(InputError, match="finite"):
        resolve_transfer(TransferSpec(preset=None, table=str(nan)), vol)
    with pytest.raises(InputError, match="file not found"):
        resolve_transfer(TransferSpec(preset=None, table=str(tmp_path / "no.npy")), vol)
