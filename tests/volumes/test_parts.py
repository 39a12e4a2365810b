"""Volumes read a part at a time (hwsim/volumes/parts.py): every box is the loaded
volume's bits, the facts (shape, type, spacing, units, value range) are the reader's,
the placeholder volume holds and pickles no voxels, and what cannot be read in parts is
refused in one line."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.spec.scene import TransferSpec, VolumeSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import load_volume, make_phantom
from hwsim.volumes.parts import is_partial, volume_parts
from models.units.voxel import converted_volume

BOXES = [
    (slice(0, 3), slice(2, 9), slice(None)),
    (slice(5, 6), slice(0, 20), 7),
    (slice(1, 12), slice(None), 0),
    (slice(0, 12), slice(4, 5), slice(None)),
]


def _files(tmp_path):
    import nrrd

    data = make_phantom("head", size=20, seed=4, z_spacing=1.7).data
    np.save(tmp_path / "v.npy", data)
    nrrd.write(
        str(tmp_path / "v.nrrd"),
        data,
        {"encoding": "raw", "spacings": [0.5, 0.5, 1.7], "content": "head (Hounsfield units)"},
        index_order="C",
    )
    big = data.astype(">i2")
    (tmp_path / "v.raw").write_bytes(b"\0" * 16 + big.tobytes())
    return {
        "npy": VolumeSpec(path=str(tmp_path / "v.npy")),
        "nrrd": VolumeSpec(path=str(tmp_path / "v.nrrd")),
        "raw": VolumeSpec(
            path=str(tmp_path / "v.raw"),
            shape=data.shape,
            dtype="int16",
            byte_order="big",
            header_bytes=16,
        ),
        "head": VolumeSpec(phantom="head", params=(("size", 20), ("seed", 4), ("z_spacing", 1.7))),
    }


@pytest.mark.parametrize("kind", ["npy", "nrrd", "raw", "head"])
def test_every_box_and_fact_is_the_loaded_volumes(kind, tmp_path):
    spec = _files(tmp_path)[kind]
    whole = load_volume(spec)
    parts = volume_parts(spec)
    volume = parts.volume()
    assert is_partial(volume) and not is_partial(whole)
    assert volume.shape == whole.shape and volume.data.dtype == whole.data.dtype
    assert volume.spacing == whole.spacing and volume.units == whole.units == "HU"
    assert volume.value_range == whole.value_range and volume.bits == whole.bits
    for z, y, x in BOXES:
        np.testing.assert_array_equal(parts.box(z, y, x), whole.data[z, y, x])


def test_the_placeholder_holds_and_pickles_no_voxels():
    parts = volume_parts(VolumeSpec(phantom="head", params=(("size", 1024),)))
    volume = parts.volume()
    assert volume.shape == (1024, 1024, 1024) and volume.data.strides == (0, 0, 0)
    assert len(pickle.dumps(volume)) < 4096
    assert pickle.loads(pickle.dumps(volume)).meta["parts"] == parts
    with pytest.raises(RuntimeError, match="never converted whole"):
        converted_volume(volume, 12)
    with pytest.raises(InputError, match="the mr preset reads percentiles of the whole volume"):
        resolve_transfer(TransferSpec(preset="mr"), volume)


def test_what_cannot_be_read_in_parts_is_refused(tmp_path):
    np.save(tmp_path / "f.npy", np.asfortranarray(np.zeros((4, 5, 6), np.int16)))
    np.save(tmp_path / "flat.npy", np.zeros((4, 5), np.int16))
    np.save(tmp_path / "short.npy", np.zeros((4, 5, 6), np.int16))
    with open(tmp_path / "short.npy", "r+b") as fh:
        fh.truncate(fh.seek(0, 2) - 2)
    (tmp_path / "v.nii").write_bytes(b"")
    cases = [
        (VolumeSpec(path=str(tmp_path / "f.npy")), "Fortran-order"),
        (VolumeSpec(path=str(tmp_path / "flat.npy")), "shape"),
        (VolumeSpec(path=str(tmp_path / "short.npy")), "holds 238 data bytes"),
        (VolumeSpec(path=str(tmp_path / "v.nii")), "cannot be read a part at a time"),
        (VolumeSpec(path=str(tmp_path / "none.npy")), "file not found"),
        (VolumeSpec(phantom="marschner-lobb"), "generated whole"),
        (VolumeSpec(phantom="head", params=(("size", 4000),)), "size: 4000 is out of range"),
    ]
    for spec, message in cases:
        with pytest.raises(InputError, match=message):
            volume_parts(spec)
