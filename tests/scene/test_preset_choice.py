"""The ``auto`` transfer preset (hwsim.spec.preset_choice): the header's modality first,
then units, then the value distribution; on the real volumes, the phantoms and synthetic
edge cases (constant, all zeros, each voxel type, tiny volumes), whole and in parts."""

from __future__ import annotations

import nibabel as nib
import nrrd
import numpy as np
import pytest
from dicom_files import write_slice
from pydicom.uid import MRImageStorage

from hwsim.spec.preset_choice import choose_preset, resolve_auto
from hwsim.spec.scene import TransferSpec, VolumeSpec
from hwsim.spec.transfer import preset_points, resolve_transfer
from hwsim.volumes import read_volume
from hwsim.volumes.modality import modality_in_text
from hwsim.volumes.parts import volume_parts
from hwsim.volumes.phantoms import make_phantom
from hwsim.volumes.volume import Volume


def mr_like(rng, dtype=np.uint8, top=200.0, shape=(12, 16, 16)) -> np.ndarray:
    """A dark background (60%) around tissue spread over the range: MR's histogram."""
    data = rng.uniform(0.1 * top, top, size=shape)
    data[rng.random(shape) < 0.6] = 0.0
    return data.astype(dtype)


def ct_like(rng, dtype=np.int16, shape=(12, 16, 16)) -> np.ndarray:
    """Air (-1000) around soft tissue (0..80) and some bone (up to 2000)."""
    data = rng.uniform(0, 80, size=shape)
    data[rng.random(shape) < 0.5] = -1000
    data[rng.random(shape) < 0.05] = 1500
    return data.astype(dtype)


def values_only(data: np.ndarray) -> Volume:
    """A volume with no header facts: only its values speak."""
    return Volume(data=data)


def test_real_volumes_by_header_and_by_values_alone(shared_data):
    ct = read_volume(shared_data / "ct_cranium.nrrd")
    mr = read_volume(shared_data / "mr_brainsmall.nrrd")
    assert choose_preset(ct) == ("ct", "NRRD header comment CT")
    assert choose_preset(mr) == ("mr", "NRRD header comment MR")
    # Without the header (and the units it implies), the values pick the same.
    bare_ct, bare_mr = values_only(ct.data), values_only(mr.data)
    assert choose_preset(bare_ct)[0] == "ct"
    assert "air in HU" in choose_preset(bare_ct)[1]
    assert choose_preset(bare_mr)[0] == "mr"
    assert "dark background" in choose_preset(bare_mr)[1]


@pytest.mark.parametrize(
    ("phantom", "params", "preset"),
    [
        ("head", {"size": 16}, "ct"),  # units HU
        ("ball", {"size": 16}, "warm"),  # a uniform ball: no tissue spread
        ("ball", {"size": 16, "dtype": "uint16", "value": 3000}, "warm"),
        ("marschner-lobb", {"size": 12}, "warm"),  # a test signal: no dark background
        ("marschner-lobb", {"size": 12, "dtype": "uint8"}, "warm"),
        ("marschner-lobb", {"size": 12, "dtype": "uint16"}, "warm"),
    ],
)
def test_phantoms(phantom, params, preset):
    assert choose_preset(make_phantom(phantom, **params))[0] == preset


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_mr_like_values_of_every_type(rng, dtype):
    top = 200.0 if dtype == np.uint8 else 4000.0
    assert choose_preset(values_only(mr_like(rng, dtype, top)))[0] == "mr"


@pytest.mark.parametrize("dtype", [np.int16, np.float32, np.float64])
def test_ct_like_values_of_every_signed_type(rng, dtype):
    name, reason = choose_preset(values_only(ct_like(rng, dtype)))
    assert name == "ct" and "air in HU" in reason


@pytest.mark.parametrize(
    "data",
    [
        np.zeros((4, 4, 4), np.uint8),  # all zeros
        np.full((4, 4, 4), 7, np.uint16),  # constant
        np.full((3, 3, 3), 0.25, np.float32),
        np.zeros((1, 1, 1), np.float64),  # tiny
        np.array([[[0, 255]]], np.uint8),  # two voxels: no tissue spread to speak of
        np.arange(64, dtype=np.uint8).reshape(4, 4, 4),  # a ramp: no dark background
        (np.arange(512).reshape(8, 8, 8) % 2).astype(np.uint8),  # a binary mask
        np.linspace(-1, 1, 27, dtype=np.float32).reshape(3, 3, 3),  # signed, not HU
    ],
    ids=["zeros", "constant-u16", "constant-f32", "1-voxel", "2-voxels", "ramp", "mask", "signed"],
)
def test_edge_cases_get_the_generic_ramp(data):
    name, reason = choose_preset(values_only(data))
    assert name == "warm" and reason.startswith("value distribution")
    preset_points("auto", values_only(data))  # and its points are valid


def test_constant_air_is_ct():
    assert choose_preset(values_only(np.full((2, 2, 2), -1000.0, np.float32)))[0] == "ct"


def test_air_share_threshold(rng):
    """CT needs at least 1% air: 1 air voxel in 1000 is not CT, 20 are."""
    data = mr_like(rng, np.float32, 300.0, (10, 10, 10))
    data.flat[0] = -1000.0
    assert choose_preset(values_only(data))[0] == "warm"  # negative: not MR either
    data = data.copy()
    data.flat[:20] = -1000.0
    assert choose_preset(values_only(data))[0] == "ct"


def test_header_modality_wins_over_values(tmp_path, rng):
    """A NRRD modality:= pair, its content, its comments; a text naming both names none."""
    ct_values = ct_like(rng)
    path = tmp_path / "kv.nrrd"
    nrrd.write(str(path), ct_values.T, {"modality": "MR"})
    assert choose_preset(read_volume(path)) == ("mr", "NRRD header modality MR")
    path = tmp_path / "content.nrrd"
    nrrd.write(str(path), mr_like(rng).T, {"content": "CT of a phantom"})
    assert choose_preset(read_volume(path)) == ("ct", "NRRD header content CT")
    both = tmp_path / "both.nrrd"
    nrrd.write(str(both), mr_like(rng).T, {"content": "MR registered to CT"})
    assert read_volume(both).modality == ""
    assert choose_preset(read_volume(both))[0] == "mr"  # the values decide


def test_nrrd_comment(tmp_path, rng):
    path = tmp_path / "c.nrrd"
    nrrd.write(str(path), mr_like(rng).T)
    text = path.read_bytes()
    path.write_bytes(text.replace(b"\n", b"\n# MRI of a knee\n", 1))
    volume = read_volume(path)
    assert (volume.modality, volume.meta["modality_from"]) == ("MR", "NRRD header comment")


def test_nifti_description(tmp_path, rng):
    image = nib.Nifti1Image(ct_like(rng).T, np.eye(4))
    image.header["descrip"] = b"T1 MR, 1.5 T"
    nib.save(image, tmp_path / "t1.nii.gz")
    assert choose_preset(read_volume(tmp_path / "t1.nii.gz")) == ("mr", "NIfTI descrip MR")
    nib.save(nib.Nifti1Image(mr_like(rng).T, np.eye(4)), tmp_path / "plain.nii")
    assert read_volume(tmp_path / "plain.nii").modality == ""


def write_mr_series(folder, data: np.ndarray) -> None:
    folder.mkdir()
    for k, plane in enumerate(data):
        write_slice(
            folder / f"IM{k}.dcm",
            plane,
            sop_class=MRImageStorage,
            modality="MR",
            position=(0.0, 0.0, float(k)),
            instance=k + 1,
        )


def test_dicom_modality_tag(tmp_path, rng):
    # Values a CT would have once rescaled (air at 0 stored): the tag decides.
    write_mr_series(tmp_path / "mr", (ct_like(rng, np.int32, (3, 8, 8)) + 1024))
    assert choose_preset(read_volume(tmp_path / "mr")) == ("mr", "DICOM Modality tag MR")


def test_parts_choose_as_the_whole_volume(tmp_path, rng):
    """--workers reads a volume in parts: the histogram is read a box at a time."""
    for data, header in (
        (mr_like(rng), {}),
        (ct_like(rng), {}),
        (mr_like(rng), {"modality": "CT"}),
    ):
        path = tmp_path / "v.nrrd"
        nrrd.write(str(path), data.T, {"encoding": "raw", **header})
        whole = choose_preset(read_volume(path))
        parts = choose_preset(volume_parts(VolumeSpec(path=str(path))).volume())
        assert parts == whole


def test_resolve_auto_keeps_what_the_scene_names(rng):
    volume = values_only(mr_like(rng))
    chosen = resolve_auto(TransferSpec(), volume)
    assert chosen.preset == "mr" and chosen.chosen_by.startswith("auto: value distribution")
    assert chosen == TransferSpec(preset="mr")  # why is not part of what is rendered
    for spec in (
        TransferSpec(preset="ct"),
        TransferSpec(preset=None, points=((0, 0, 0, 0, 0), (1, 1, 1, 1, 1))),
    ):
        assert resolve_auto(spec, volume) is spec
    # resolve_transfer's own auto agrees with the resolved preset
    auto = resolve_transfer(TransferSpec(), volume)
    named = resolve_transfer(chosen, volume)
    assert np.array_equal(auto.values, named.values) and np.array_equal(auto.rgba, named.rgba)


def test_a_brick_keeps_its_volume_modality(rng):
    volume = Volume(data=ct_like(rng), modality="MR", meta={"modality_from": "test"})
    brick = volume.brick((0, 0, 0), (2, 16, 16), "b0")
    assert choose_preset(brick) == ("mr", "test MR")


@pytest.mark.parametrize(
    ("text", "found"),
    [
        ("CT head, Hounsfield units", "CT"),
        ("MR head (UNC MRI)", "MR"),
        ("magnetic resonance angiography", "MR"),
        ("Computed Tomography", "CT"),
        ("PET/CT", "CT"),
        ("MR and CT fused", ""),
        ("actor, mri-like", ""),  # words only, acronyms in capitals
        ("", ""),
    ],
)
def test_modality_words(text, found):
    assert modality_in_text(text) == found
