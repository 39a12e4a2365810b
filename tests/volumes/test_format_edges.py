"""Volume formats at their edges: ASCII NRRD, byte and line skips, empty and truncated
files of every format, DICOM slices without pixels, NIfTI headers nibabel only logs
about.  The property test at the end generates NRRD headers with random fields and
asserts the class: a correct read, or an InputError naming the file, nothing else.
"""

from __future__ import annotations

import bz2
import gzip
import struct
import subprocess
import sys

import numpy as np
import pytest
from dicom_files import write_dicomdir, write_slice
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from hwsim.core.errors import InputError
from hwsim.volumes.readers import read_volume

#: NRRD type names and the NumPy type of each.
NRRD_TYPES = {
    "uint8": np.uint8,
    "int8": np.int8,
    "short": np.int16,
    "ushort": np.uint16,
    "int": np.int32,
    "uint": np.uint32,
    "int64": np.int64,
    "float": np.float32,
    "double": np.float64,
}


def nrrd_bytes(
    data: np.ndarray,
    type_name: str,
    *,
    encoding: str = "raw",
    endian: str | None = "little",
    byte_skip: int | None = None,
    line_skip: int = 0,
    junk: int = 0,
    sizes: str | None = None,
) -> bytes:
    """A NRRD file of ``data`` (z, y, x), with ``junk`` bytes before the data that
    ``byte_skip`` skips (decoded bytes for compressed data) and ``line_skip`` lines."""
    fields = [
        "NRRD0004",
        f"type: {type_name}",
        f"dimension: {data.ndim}",
        f"sizes: {sizes or ' '.join(str(n) for n in data.shape[::-1])}",
        f"encoding: {encoding}",
    ]
    if endian:
        fields.append(f"endian: {endian}")
    if byte_skip is not None:
        fields.append(f"byte skip: {byte_skip}")
    if line_skip:
        fields.append(f"line skip: {line_skip}")
    head = ("\n".join(fields) + "\n\n").encode() + b"skipped line\n" * line_skip
    if encoding in ("ascii", "text", "txt"):
        values = [repr(float(v)) if data.dtype.kind == "f" else str(int(v)) for v in data.ravel()]
        lines = [" ".join(values[i : i + 5]) for i in range(0, len(values), 5)]
        return head + b"x" * junk + ("\n".join(lines) + "\n").encode()
    order = ">" if endian == "big" else "<"
    payload = b"\xa5" * junk + data.astype(data.dtype.newbyteorder(order)).tobytes()
    if encoding in ("gzip", "gz"):
        payload = gzip.compress(payload)
    elif encoding in ("bzip2", "bz2"):
        payload = bz2.compress(payload)
    return head + payload


def read_back(tmp_path, content: bytes, name: str = "v.nrrd"):
    path = tmp_path / name
    path.write_bytes(content)
    return path, read_volume(path)


def refused(tmp_path, content: bytes, *fragments: str, name: str = "v.nrrd") -> str:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        read_volume(path)
    text = str(info.value)
    assert str(path) in text and "\n" not in text, text
    for fragment in fragments:
        assert fragment in text, (fragment, text)
    return text


SAMPLE = (np.arange(60, dtype=np.int64).reshape(3, 4, 5) * 37 - 900).astype(np.int16)


@pytest.mark.parametrize("encoding", ["ascii", "text", "txt"])
@pytest.mark.parametrize("type_name", ["short", "uint8", "float", "double"])
def test_ascii_nrrd_reads_as_the_same_data_raw(tmp_path, encoding, type_name):
    data = SAMPLE.astype(NRRD_TYPES[type_name]) if type_name != "uint8" else SAMPLE % 251
    data = data.astype(NRRD_TYPES[type_name]) / (3 if type_name in ("float", "double") else 1)
    data = data.astype(NRRD_TYPES[type_name])
    _, text = read_back(tmp_path, nrrd_bytes(data, type_name, encoding=encoding), "a.nrrd")
    _, raw = read_back(tmp_path, nrrd_bytes(data, type_name), "r.nrrd")
    assert text.data.dtype == raw.data.dtype and text.data.shape == (3, 4, 5)
    np.testing.assert_array_equal(text.data, raw.data)
    np.testing.assert_array_equal(raw.data, data)


def test_ascii_nrrd_with_line_and_byte_skip(tmp_path):
    content = nrrd_bytes(SAMPLE, "short", encoding="ascii", line_skip=2, byte_skip=7, junk=7)
    np.testing.assert_array_equal(read_back(tmp_path, content)[1].data, SAMPLE)


@pytest.mark.parametrize(
    "values,fragment",
    [("1 2 3", "holds 3 values but the header declares 60"), ("1 " * 61, "more than 60 values")],
)
def test_ascii_nrrd_with_too_few_or_many_values_says_both_counts(tmp_path, values, fragment):
    head = nrrd_bytes(SAMPLE, "short", encoding="ascii").split(b"\n\n")[0]
    refused(tmp_path, head + b"\n\n" + values.encode() + b"\n", fragment)


@pytest.mark.parametrize("token,fragment", [("70000", "out of bounds"), ("abc", "abc")])
def test_ascii_nrrd_with_a_bad_number_is_refused(tmp_path, token, fragment):
    head = nrrd_bytes(SAMPLE, "short", encoding="ascii").split(b"\n\n")[0]
    values = " ".join(["1"] * 59 + [token])
    refused(tmp_path, head + b"\n\n" + values.encode(), "ASCII data", fragment)


@pytest.mark.parametrize("encoding", ["raw", "gzip", "bzip2"])
def test_byte_skip_skips_that_many_data_bytes(tmp_path, encoding):
    content = nrrd_bytes(SAMPLE, "short", encoding=encoding, byte_skip=11, junk=11)
    np.testing.assert_array_equal(read_back(tmp_path, content)[1].data, SAMPLE)


def test_byte_skip_minus_one_reads_the_last_bytes_of_raw_data(tmp_path):
    content = nrrd_bytes(SAMPLE, "short", byte_skip=-1, junk=13)
    np.testing.assert_array_equal(read_back(tmp_path, content)[1].data, SAMPLE)


@pytest.mark.parametrize(
    "encoding,skip",
    [("raw", -2), ("raw", -1000), ("gzip", -1), ("ascii", -1), ("bzip2", -5)],
)
def test_other_negative_byte_skips_are_refused_by_name(tmp_path, encoding, skip):
    content = nrrd_bytes(SAMPLE, "short", encoding=encoding, byte_skip=skip)
    refused(tmp_path, content, "byte skip", str(skip))


def test_a_byte_skip_past_the_end_is_refused(tmp_path):
    refused(tmp_path, nrrd_bytes(SAMPLE, "short", byte_skip=10**15), "byte skip", "past the end")


def test_a_huge_byte_skip_of_compressed_data_keeps_nothing_skipped(tmp_path):
    content = nrrd_bytes(SAMPLE, "short", encoding="gzip", byte_skip=10**15)
    refused(tmp_path, content, "holds 0 bytes but the header declares 120")


def test_byte_skip_minus_one_with_too_little_data_says_both_counts(tmp_path):
    content = nrrd_bytes(SAMPLE, "short", byte_skip=-1)[:-10]
    refused(tmp_path, content, "holds 110 bytes but the header declares 120")


def test_an_empty_nrrd_is_one_line(tmp_path):
    refused(tmp_path, b"", "empty file")


@pytest.mark.parametrize("cut", ["\n\n", "\n", ""])
def test_a_header_only_nrrd_is_one_line(tmp_path, cut):
    head = nrrd_bytes(SAMPLE, "short").split(b"\n\n")[0] + cut.encode()
    refused(tmp_path, head)


def _npy(data):
    import io

    buffer = io.BytesIO()
    np.save(buffer, data)
    return buffer.getvalue()


def _nifti(data):
    import nibabel as nib

    return nib.Nifti1Image(data.T, np.eye(4)).to_bytes()


#: Each format's bytes for SAMPLE, and the data bytes it declares.
FORMATS = {
    "v.npy": (_npy, 120),
    "v.nrrd": (lambda d: nrrd_bytes(d, "short"), 120),
    "v.nii": (_nifti, 472),
    "v.raw": (lambda d: d.tobytes(), 120),
}


@pytest.mark.parametrize("name", FORMATS)
@pytest.mark.parametrize("cut", [1, 2, 50])
def test_a_truncated_file_of_every_format_says_expected_and_actual(tmp_path, name, cut):
    make, declared = FORMATS[name]
    path = tmp_path / name
    path.write_bytes(make(SAMPLE)[:-cut])
    extra = {"shape": (3, 4, 5), "dtype": "int16"} if name.endswith(".raw") else {}
    with pytest.raises(InputError) as info:
        read_volume(path, **extra)
    text = str(info.value)
    assert str(path) in text and str(declared) in text and str(declared - cut) in text, text


def _dicom_slice(path, z, *, pixels=True):
    """A 4 x 4 CT slice at height ``z`` of one series (tests/volumes/dicom_files.py)."""
    from pydicom.uid import CTImageStorage

    stored = np.full((4, 4), z, np.uint16)
    write_slice(
        path, stored, sop_class=CTImageStorage, modality="CT", position=(0.0, 0.0, z),
        series="1.2.3.4", pixels=pixels,
    )  # fmt: skip


@pytest.mark.parametrize("name", ["s2.dcm", "IM0002"])
def test_a_dicom_slice_without_pixel_data_is_refused_naming_it(tmp_path, name):
    for z in (0, 1, 3):
        _dicom_slice(tmp_path / f"s{z}.dcm", z)
    _dicom_slice(tmp_path / name, 2, pixels=False)
    with pytest.raises(InputError, match="without pixel data") as info:
        read_volume(tmp_path)
    assert str(tmp_path / name) in str(info.value)


def test_a_dicomdir_beside_the_series_is_still_skipped(tmp_path):
    for z in (0, 1, 2):
        _dicom_slice(tmp_path / f"s{z}.dcm", z)
    write_dicomdir(tmp_path / "DICOMDIR")
    assert read_volume(tmp_path).data.shape == (3, 4, 4)


@pytest.mark.parametrize("dim0", [0, 8, 9, -1, 300])
def test_a_nifti_with_a_bad_dim0_is_hwsims_one_line_only(tmp_path, dim0):
    """nibabel guesses the byte order from dim[0] and logs its repairs to stderr; the
    user sees hwsim's line and nothing else (a child process: nibabel's log handler
    writes to the real stderr)."""
    content = bytearray(_nifti(SAMPLE))
    content[40:42] = struct.pack("<h", dim0)
    path = tmp_path / "v.nii"
    path.write_bytes(bytes(content))
    done = subprocess.run(
        [sys.executable, "-m", "hwsim.cli.commands", "render", "--volume", str(path)]
        + ["--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=600,  # a hang guard only
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr == f"hwsim: error: {path}: dim[0]: {dim0} dimensions (allowed: 1 .. 7)\n"


# --------------------------------------------------------------------- the property


@st.composite
def nrrd_cases(draw):
    """A NRRD file with random fields, and whether it is a valid file of its data."""
    type_name = draw(st.sampled_from([*NRRD_TYPES, "block", "quaternion", ""]))
    dtype = NRRD_TYPES.get(type_name, np.int16)
    shape = tuple(draw(st.lists(st.integers(1, 4), min_size=1, max_size=4)))
    info = np.iinfo(dtype) if np.dtype(dtype).kind in "iu" else None
    lo, hi = (max(info.min, -30000), min(info.max, 30000)) if info else (-1e6, 1e6)
    values = draw(st.lists(st.integers(int(lo), int(hi)), min_size=1, max_size=1))
    rng = np.random.default_rng(values[0] & 0xFFFF)
    data = rng.uniform(lo, hi, size=shape).astype(dtype)
    encoding = draw(st.sampled_from(["raw", "ascii", "text", "txt", "gzip", "gz", "bzip2", "zip"]))
    endian = draw(st.sampled_from(["little", "big", None, "middle"]))
    skip = draw(st.sampled_from([None, 0, 3, -1, -2, -7, 10**12]))
    lines = draw(st.sampled_from([0, 0, 1, 3]))
    junk = draw(st.integers(0, 9)) if skip == -1 else (skip if skip and 0 < skip < 100 else 0)
    sizes = draw(st.sampled_from([None, None, None, "0 2 2", "-3 2 2", "2 x 2", "2 2 2 2 2"]))
    cut = draw(st.sampled_from([0, 0, 0, 1, 5, -1, -4]))  # bytes dropped (< 0: added)
    content = nrrd_bytes(
        data,
        type_name,
        encoding=encoding,
        endian=endian,
        byte_skip=skip,
        line_skip=lines,
        junk=junk,
        sizes=sizes,
    )
    content = content[:-cut] if cut > 0 else content + b"7 " * -cut
    multibyte = np.dtype(dtype).itemsize > 1 and encoding not in ("ascii", "text", "txt")
    valid = (
        type_name in NRRD_TYPES
        and len(shape) == 3
        and encoding != "zip"
        and (endian in ("little", "big") or (endian is None and not multibyte))
        and (skip in (None, 0, 3) or (skip == -1 and encoding == "raw"))
        and sizes is None
        and cut == 0
    )
    # A cut ASCII number still parses and the last bytes of a raw file are its data with
    # byte skip -1: there a changed length can be a different, well-formed file.
    text = encoding in ("ascii", "text", "txt")
    exact = cut == 0 or not (text or (skip == -1 and encoding == "raw"))
    return content, data, valid, exact


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(case=nrrd_cases())
def test_any_nrrd_is_read_right_or_refused_naming_it(tmp_path, case):
    """The class: whatever the header says and however the data is cut, a read returns
    exactly the data written, or raises one InputError naming the file; a valid file is
    always read, a cut one never."""
    content, data, valid, exact = case
    path = tmp_path / "case.nrrd"
    path.write_bytes(content)
    try:
        volume = read_volume(path)
    except InputError as exc:
        assert str(path) in str(exc) and "\n" not in str(exc), exc
        assert not valid, f"a valid file was refused: {exc}"
        return
    if not exact:
        return
    assert volume.data.shape == data.shape, (volume.data.shape, data.shape)
    np.testing.assert_array_equal(volume.data.astype(np.float64), data.astype(np.float64))


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    name=st.sampled_from(["v.nii", "v.npy"]),
    edits=st.lists(st.tuples(st.integers(0, 351), st.integers(0, 255)), min_size=1, max_size=4),
    keep=st.one_of(st.none(), st.integers(0, 500)),
)
@example(name="v.nii", edits=[(115, 0x70)], keep=None)  # scl_slope 3.2e29, an integer
@example(name="v.npy", edits=[(71, ord("("))], keep=None)  # the header dict left open
def test_any_damaged_nifti_or_npy_header_is_read_or_refused_quietly(
    tmp_path, capfd, name, edits, keep
):
    """A few bytes of a NIfTI or .npy header changed (and perhaps the file cut): the read
    returns a volume or raises one InputError naming the file, and nothing reaches stderr
    on a refusal (nibabel's own log lines included).  Found: a 1e30 scl_slope overflowed
    int64 scaling; a broken .npy header dict raised tokenize.TokenError."""
    content = bytearray(FORMATS[name][0](SAMPLE))
    for pos, value in edits:
        if pos < min(len(content), 352 if name.endswith(".nii") else 128):
            content[pos] = value
    path = tmp_path / name
    path.write_bytes(bytes(content[:keep] if keep is not None else content))
    capfd.readouterr()
    try:
        read_volume(path)
    except InputError as exc:
        assert str(path) in str(exc) and "\n" not in str(exc), exc
        assert capfd.readouterr().err == ""


@pytest.mark.parametrize(
    "key,value",
    [
        ("PixelSpacing", [1.0]),
        ("PixelSpacing", [1.0, 2.0, 3.0]),
        ("ImageOrientationPatient", [1, 0, 0, 0, 1]),
        ("ImagePositionPatient", [0.0, 0.0]),
    ],
)
def test_a_dicom_vector_of_the_wrong_length_is_refused_naming_file_and_key(tmp_path, key, value):
    """Found by editing slices' tags: these were ValueError/TypeError (internal errors)."""
    import pydicom

    for z in (0, 1, 2):
        _dicom_slice(tmp_path / f"s{z}.dcm", z)
    ds = pydicom.dcmread(tmp_path / "s0.dcm")
    setattr(ds, key, value)
    ds.save_as(tmp_path / "s0.dcm")
    with pytest.raises(InputError, match=f"{key}.*finite numbers") as info:
        read_volume(tmp_path)
    assert str(tmp_path / "s0.dcm") in str(info.value)


@pytest.mark.parametrize("cut", [9, 30])
def test_a_cut_nii_gz_says_its_stream_is_cut(tmp_path, cut):
    """nibabel said 'Cannot work out file type' of a .nii.gz cut inside its stream."""
    path = tmp_path / "v.nii.gz"
    path.write_bytes(gzip.compress(_nifti(SAMPLE))[:-cut])
    with pytest.raises(InputError, match="damaged gzip stream after") as info:
        read_volume(path)
    assert str(path) in str(info.value)
