"""Readers: every format round-trips an asymmetric volume written by its own library, so
axis order, spacing and type are proven; every bad input is an InputError naming the file."""

from __future__ import annotations

import gzip

import nibabel as nib
import nrrd
import numpy as np
import pytest
from dicom_files import write_slice
from pydicom.uid import CTImageStorage

from hwsim.core.errors import InputError
from hwsim.spec.scene import VolumeSpec
from hwsim.volumes import EXTENSIONS, load_volume, read_volume

SHAPE = (3, 4, 5)  # (z, y, x): distinct sizes per axis
SPACING = (2.5, 1.25, 0.5)  # (z, y, x): distinct spacings per axis


@pytest.fixture
def asym() -> np.ndarray:
    """int16 (z, y, x) volume with a distinct value in every voxel: v = 100z + 10y + x - 1100."""
    z, y, x = np.indices(SHAPE)
    return (100 * z + 10 * y + x - 1100).astype(np.int16)


def assert_names(exc: pytest.ExceptionInfo, path) -> None:
    assert str(path) in str(exc.value), str(exc.value)


# --------------------------------------------------------------------------- npy


def test_npy_round_trip_keeps_axis_order_type_and_default_spacing(tmp_path, asym):
    path = tmp_path / "vol.npy"
    np.save(path, asym)
    vol = read_volume(path)
    assert vol.shape == SHAPE and vol.data.dtype == np.int16
    np.testing.assert_array_equal(vol.data, asym)
    assert vol.data[2, 3, 4] == 200 + 30 + 4 - 1100  # z, y, x
    assert vol.spacing == (1.0, 1.0, 1.0) and vol.name == "vol" and vol.source == str(path)
    assert vol.units == "HU" and vol.bits == 16  # signed, min -1100 <= -900
    assert read_volume(path, spacing=SPACING).spacing == SPACING


@pytest.mark.parametrize(
    ("array", "dtype"),
    [
        (np.arange(60, dtype=">i2").reshape(SHAPE), np.int16),  # big-endian -> native
        (np.arange(60, dtype=">f8").reshape(SHAPE), np.float64),
        ((np.arange(60) % 2).astype(bool).reshape(SHAPE), np.uint8),
        (np.arange(60, dtype=np.uint32).reshape(SHAPE) * 1000, np.uint16),  # max 59000 fits
        # 32-bit voxels that need them: containers of fields (VolumePro 1000)
        (np.arange(60, dtype=">u4").reshape(SHAPE) << 20, np.uint32),
        (np.arange(60, dtype=np.int64).reshape(SHAPE) - 30, np.int16),
        (np.arange(60, dtype=np.float16).reshape(SHAPE), np.float32),
    ],
)
def test_lossless_type_conversions(tmp_path, array, dtype):
    np.save(tmp_path / "v.npy", array)
    vol = read_volume(tmp_path / "v.npy")
    assert vol.data.dtype == np.dtype(dtype) and vol.data.dtype.isnative
    np.testing.assert_array_equal(vol.data, array.astype(np.float64))


def test_units_rule_only_marks_signed_data_reaching_air(tmp_path, asym):
    np.save(tmp_path / "mr.npy", (asym + 1100).astype(np.uint16))
    np.save(tmp_path / "f.npy", asym.astype(np.float32))
    assert read_volume(tmp_path / "mr.npy").units == ""
    assert read_volume(tmp_path / "f.npy").units == ""  # floats: only if a header says so


@pytest.mark.parametrize(
    ("array", "needle"),
    [
        (np.arange(60, dtype=np.int32).reshape(SHAPE) * 10**6, "do not fit"),
        (np.zeros(SHAPE, dtype=np.complex64), "not supported"),
        (np.zeros((4, 5), dtype=np.uint8), "3-D"),
        (np.zeros((1, 4, 5, 2), dtype=np.uint8), "3-D"),
        (np.zeros((3, 0, 5), dtype=np.uint8), "length zero"),
        (np.full(SHAPE, np.nan, dtype=np.float32), "NaN"),
        (np.where(np.eye(5)[None, :4] > 0, np.inf, 0.0), "NaN or Inf"),
    ],
)
def test_bad_npy_data_is_an_input_error_naming_the_file(tmp_path, array, needle):
    path = tmp_path / "bad.npy"
    np.save(path, array)
    with pytest.raises(InputError, match=needle) as exc:
        read_volume(path)
    assert_names(exc, path)


def test_pickled_npy_is_refused(tmp_path):
    path = tmp_path / "obj.npy"
    np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(InputError) as exc:
        read_volume(path)
    assert_names(exc, path)


# --------------------------------------------------------------------------- NRRD


@pytest.mark.parametrize("name", ["vol.nrrd", "vol.nhdr"])
def test_nrrd_round_trip_attached_and_detached(tmp_path, asym, name):
    path = tmp_path / name
    nrrd.write(str(path), asym, {"spacings": SPACING[::-1]}, index_order="C")  # x fastest
    if name.endswith(".nhdr"):
        assert (tmp_path / "vol.raw.gz").is_file()  # the data really is detached
    vol = read_volume(path)
    np.testing.assert_array_equal(vol.data, asym)
    assert vol.spacing == SPACING and vol.name == "vol"


def test_nrrd_spacing_from_space_directions(tmp_path, asym):
    path = tmp_path / "dirs.nrrd"
    dirs = np.array([[0.0, 0.5, 0.0], [1.25, 0.0, 0.0], [0.0, 0.0, -2.5]])  # x, y, z rows
    header = {"space": "left-posterior-superior", "space directions": dirs}
    nrrd.write(str(path), asym, header, index_order="C")
    assert read_volume(path).spacing == SPACING


@pytest.mark.parametrize("change", [-2, +2])
def test_nrrd_detached_data_of_the_wrong_size(tmp_path, asym, change):
    path = tmp_path / "v.nhdr"
    nrrd.write(str(path), asym, {"encoding": "raw"}, index_order="C")
    data = tmp_path / "v.raw"
    raw = data.read_bytes()
    data.write_bytes(raw[:change] if change < 0 else raw + b"\0" * change)
    with pytest.raises(InputError, match="NRRD") as exc:
        read_volume(path)
    assert_names(exc, path)


def test_nrrd_header_that_lies_about_its_size(tmp_path, asym):
    path = tmp_path / "lies.nrrd"
    nrrd.write(str(path), asym, {"encoding": "raw"}, index_order="C")
    text = path.read_bytes().replace(b"sizes: 5 4 3", b"sizes: 5 4 9")
    path.write_bytes(text)
    with pytest.raises(InputError) as exc:
        read_volume(path)
    assert_names(exc, path)


def test_nrrd_garbage_and_2d(tmp_path):
    junk = tmp_path / "junk.nrrd"
    junk.write_bytes(b"not a nrrd at all\n")
    with pytest.raises(InputError) as exc:
        read_volume(junk)
    assert_names(exc, junk)
    flat = tmp_path / "flat.nrrd"
    nrrd.write(str(flat), np.zeros((4, 5), np.uint8), index_order="C")
    with pytest.raises(InputError, match="3-D") as exc:
        read_volume(flat)
    assert_names(exc, flat)


def test_real_volumes_load_with_shape_spacing_and_units(shared_data):
    ct = read_volume(shared_data / "ct_cranium.nrrd")
    assert ct.shape == (108, 256, 256) and ct.data.dtype == np.int16
    assert ct.spacing == pytest.approx((1.5, 0.957, 0.957))
    assert ct.units == "HU" and ct.value_range == (-1024.0, 2986.0) and ct.bits == 16
    mr = read_volume(shared_data / "mr_brainsmall.nrrd")
    assert mr.shape == (84, 128, 128) and mr.data.dtype == np.uint8
    assert mr.spacing == (1.0, 1.0, 1.0) and mr.units == "" and mr.bits == 8


# --------------------------------------------------------------------------- NIfTI


def nifti(data_zyx: np.ndarray, spacing_zyx=SPACING) -> nib.Nifti1Image:
    """A NIfTI image of (z, y, x) data: nibabel wants (x, y, z)."""
    affine = np.diag([*spacing_zyx[::-1], 1.0])
    return nib.Nifti1Image(np.transpose(data_zyx, (2, 1, 0)), affine)


@pytest.mark.parametrize("name", ["vol.nii", "vol.nii.gz"])
def test_nifti_round_trip(tmp_path, asym, name):
    path = tmp_path / name
    nib.save(nifti(asym), path)
    vol = read_volume(path)
    np.testing.assert_array_equal(vol.data, asym)
    assert vol.data.flags.c_contiguous
    assert vol.spacing == SPACING and vol.name == "vol" and vol.units == "HU"


def test_nifti_4d_with_one_time_point_is_squeezed_more_is_refused(tmp_path, asym):
    one = tmp_path / "one.nii"
    data4 = np.transpose(asym, (2, 1, 0))[..., None]
    nib.save(nib.Nifti1Image(data4, np.eye(4)), one)
    np.testing.assert_array_equal(read_volume(one).data, asym)
    two = tmp_path / "two.nii"
    nib.save(nib.Nifti1Image(np.concatenate([data4, data4], axis=3), np.eye(4)), two)
    with pytest.raises(InputError, match="time points") as exc:
        read_volume(two)
    assert_names(exc, two)


def test_nifti_integer_scaling_applied_when_exact_else_recorded(tmp_path, asym):
    exact = nifti(asym)
    exact.header.set_slope_inter(2, -5)
    nib.save(exact, tmp_path / "exact.nii")
    vol = read_volume(tmp_path / "exact.nii")
    assert vol.data.dtype == np.int16 and "scl_slope" not in vol.meta
    np.testing.assert_array_equal(vol.data, asym.astype(np.int64) * 2 - 5)
    inexact = nifti(asym)
    inexact.header.set_slope_inter(0.5, 0.25)
    nib.save(inexact, tmp_path / "inexact.nii")
    vol = read_volume(tmp_path / "inexact.nii")
    np.testing.assert_array_equal(vol.data, asym)  # raw integers kept
    assert vol.meta["scl_slope"] == 0.5 and vol.meta["scl_inter"] == 0.25
    floats = nifti(asym.astype(np.float32))
    floats.header.set_slope_inter(0.5, 0.25)
    nib.save(floats, tmp_path / "floats.nii")
    np.testing.assert_allclose(read_volume(tmp_path / "floats.nii").data, asym * 0.5 + 0.25)


@pytest.mark.parametrize("change", [-4, +4])
def test_nifti_data_of_the_wrong_size(tmp_path, asym, change):
    path = tmp_path / "v.nii"
    nib.save(nifti(asym), path)
    raw = path.read_bytes()
    path.write_bytes(raw[:change] if change < 0 else raw + b"\0" * change)
    with pytest.raises(InputError) as exc:
        read_volume(path)
    assert_names(exc, path)


def test_nifti_gz_with_trailing_data_and_garbage(tmp_path, asym):
    path = tmp_path / "v.nii.gz"
    nib.save(nifti(asym), path)
    path.write_bytes(gzip.compress(gzip.decompress(path.read_bytes()) + b"\0" * 8))
    with pytest.raises(InputError, match="header describes") as exc:
        read_volume(path)
    assert_names(exc, path)
    junk = tmp_path / "junk.nii"
    junk.write_bytes(b"\0" * 10)
    with pytest.raises(InputError) as exc:
        read_volume(junk)
    assert_names(exc, junk)


# --------------------------------------------------------------------------- raw


def test_raw_with_header_and_big_endian(tmp_path, asym):
    path = tmp_path / "v.raw"
    path.write_bytes(b"H" * 16 + asym.astype(">i2").tobytes())
    vol = read_volume(path, shape=SHAPE, dtype="int16", byte_order="big", header_bytes=16)
    np.testing.assert_array_equal(vol.data, asym)
    assert vol.data.dtype == np.int16 and vol.data.dtype.isnative


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"shape": SHAPE, "dtype": "uint16"}, "needs 120"),  # file holds 136 bytes
        ({"shape": (3, 4, 6), "dtype": "int16", "header_bytes": 16}, "needs 160"),
        ({"shape": SHAPE, "dtype": "int16", "header_bytes": 8}, "needs 128"),
        ({"dtype": "int16"}, "explicit shape"),
        ({"shape": SHAPE}, "explicit shape"),
        ({"shape": SHAPE, "dtype": "voxel"}, "unknown voxel type"),
        ({"shape": SHAPE, "dtype": "int16", "byte_order": "middle"}, "byte order"),
    ],
)
def test_raw_errors(tmp_path, asym, kwargs, needle):
    path = tmp_path / "v.raw"
    path.write_bytes(b"H" * 16 + asym.tobytes())  # 136 bytes
    with pytest.raises(InputError, match=needle) as exc:
        read_volume(path, **kwargs)
    assert_names(exc, path)


# --------------------------------------------------------------------------- DICOM


def write_ct_slice(path, hu, *, position, normal_rows, instance, series, rows_cols=None):
    """One CT slice: 12-bit unsigned stored values, rescale intercept -1024 -> HU."""
    write_slice(
        path,
        hu.astype(np.int32) + 1024,
        sop_class=CTImageStorage,
        modality="CT",
        position=position,
        orientation=[*normal_rows[0], *normal_rows[1]],
        spacing=(1.25, 0.5),  # between rows (y), between columns (x)
        thickness=2.5,
        bits_stored=12,
        study="1.2.3",
        series=series,
        instance=instance,
        rows_cols=rows_cols,
        RescaleSlope=1,
        RescaleIntercept=-1024,
        RescaleType="HU",
    )


def write_series(folder, volume, *, shuffle=(2, 0, 3, 1), instances=True, series="1.2.3.4"):
    """A tilted CT series: slice k at origin + 2.5 k n, files and InstanceNumbers shuffled."""
    folder.mkdir(exist_ok=True)
    row, col = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.8, 0.6])
    normal = np.cross(row, col)
    for name_index, k in enumerate(shuffle):
        write_ct_slice(
            folder / f"IM{name_index:03d}.dcm",
            volume[k],
            position=np.array([-10.0, 4.0, 7.0]) + 2.5 * k * normal,
            normal_rows=(row, col),
            instance=(len(shuffle) - k) if instances else None,  # reversed: positions win
            series=series,
        )
    return folder


@pytest.fixture
def ct4(asym) -> np.ndarray:
    """(z=4, y=4, x=5) HU volume reaching air."""
    return np.concatenate([asym + 100, asym[:1] + 1100]).astype(np.int16)


def test_dicom_series_sorted_by_position_rescaled_to_hu(tmp_path, ct4):
    folder = write_series(tmp_path / "series", ct4)
    (folder / "README").write_text("not DICOM; skipped")
    vol = read_volume(folder)
    np.testing.assert_array_equal(vol.data, ct4)
    assert vol.data.dtype == np.int16 and vol.units == "HU"
    assert vol.spacing == pytest.approx((2.5, 1.25, 0.5))
    assert vol.bits == 12 and vol.meta["bits_stored"] == 12  # -1000 .. 34 fits 12 bits signed
    assert vol.meta["slice_order"] == "position" and vol.name == "series"


def test_dicom_bits_widen_when_rescaled_values_need_it(tmp_path, ct4):
    bright = ct4.copy()
    bright[0, 0, 0] = 3000  # stored 4024 fits 12 bits; 3000 HU needs 13 bits signed
    vol = read_volume(write_series(tmp_path / "s", bright))
    assert vol.bits == 16 and vol.data[0, 0, 0] == 3000


def test_dicom_falls_back_to_instance_number(tmp_path, ct4):
    folder = write_series(tmp_path / "s", ct4)
    for path in folder.iterdir():  # drop positions; InstanceNumber is N - k (reversed)
        import pydicom

        ds = pydicom.dcmread(path)
        del ds.ImagePositionPatient
        ds.save_as(path, enforce_file_format=True)
    vol = read_volume(folder)
    np.testing.assert_array_equal(vol.data, ct4[::-1])
    assert vol.meta["slice_order"] == "instance" and vol.spacing[0] == 2.5  # SliceThickness


@pytest.mark.parametrize(
    ("series", "pixels", "needle"),
    [
        ("9.9.9", np.zeros((4, 5), np.int16), "SeriesInstanceUID 9.9.9 differs from 1.2.3.4"),
        ("1.2.3.4", np.zeros((4, 6), np.int16), "Columns 6 differs from 5"),
    ],
)
def test_dicom_mixed_series_and_inconsistent_sizes_name_the_file(
    tmp_path, ct4, series, pixels, needle
):
    folder = write_series(tmp_path / "mix", ct4)
    write_ct_slice(
        folder / "IM009.dcm",
        pixels,
        position=(0, 0, 99),
        normal_rows=((1, 0, 0), (0, 0.8, 0.6)),
        instance=9,
        series=series,
    )
    with pytest.raises(InputError, match=needle) as exc:
        read_volume(folder)
    assert_names(exc, folder / "IM009.dcm")


def test_dicom_duplicate_positions_are_refused(tmp_path, ct4):
    folder = write_series(tmp_path / "dup", ct4, shuffle=(0, 1, 1))
    with pytest.raises(InputError, match="same slice position") as exc:
        read_volume(folder)
    assert "dup/IM00" in str(exc.value)


def test_dicom_empty_folder_and_broken_dcm(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no DICOM images") as exc:
        read_volume(empty)
    assert_names(exc, empty)
    (empty / "x.dcm").write_bytes(b"garbage")
    with pytest.raises(InputError) as exc:
        read_volume(empty)
    assert_names(exc, empty / "x.dcm")


# --------------------------------------------------------------------------- dispatch


def test_missing_file_and_unknown_extension(tmp_path):
    missing = tmp_path / "none.nrrd"
    with pytest.raises(InputError, match="file not found") as exc:
        read_volume(missing)
    assert_names(exc, missing)
    odd = tmp_path / "v.tiff"
    odd.write_bytes(b"")
    with pytest.raises(InputError, match="unknown volume file type") as exc:
        read_volume(odd)
    assert_names(exc, odd)
    for ext in (".npy", ".nrrd", ".nhdr", ".nii.gz", ".raw", "DICOM"):
        assert ext in str(exc.value)
    assert len(EXTENSIONS) == 7


def test_raw_layout_keys_are_refused_for_self_describing_files(tmp_path, asym):
    path = tmp_path / "v.npy"
    np.save(path, asym)
    with pytest.raises(InputError, match="only apply to .raw") as exc:
        read_volume(path, shape=SHAPE)
    assert_names(exc, path)


def test_load_volume_resolves_relative_paths_and_overrides_spacing(tmp_path, asym):
    np.save(tmp_path / "v.npy", asym)
    vol = load_volume(VolumeSpec(path="v.npy", spacing=SPACING), base_dir=tmp_path)
    np.testing.assert_array_equal(vol.data, asym)
    assert vol.spacing == SPACING
    raw = tmp_path / "v.raw"
    raw.write_bytes(asym.tobytes())
    spec = VolumeSpec(path=str(raw), shape=SHAPE, dtype="int16")
    np.testing.assert_array_equal(load_volume(spec).data, asym)
    ball = load_volume(VolumeSpec(phantom="ball", params=(("size", 8),), spacing=(2.0, 1.0, 1.0)))
    assert ball.shape == (8, 8, 8) and ball.spacing == (2.0, 1.0, 1.0)
    assert ball.source == "ball:size=8"


def test_load_volume_without_source_and_bad_spacing_override(tmp_path, asym):
    with pytest.raises(InputError, match="path or a phantom"):
        load_volume(VolumeSpec())
    np.save(tmp_path / "v.npy", asym)
    with pytest.raises(InputError, match="spacing") as exc:
        read_volume(tmp_path / "v.npy", spacing=(1.0, 0.0, 1.0))
    assert_names(exc, tmp_path / "v.npy")
