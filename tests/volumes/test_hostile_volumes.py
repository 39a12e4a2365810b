"""Files that lie: every one ends in one exit-2 line naming the file, before allocating.

The corpus of issue 14: headers that declare far more data than the file holds (or than
memory holds), compressed payloads that inflate past their declared size, truncated and
mislabelled files, and geometry that would be silently wrong.
"""

from __future__ import annotations

import bz2
import gzip
import os
import subprocess
import sys
import zlib

import nibabel as nib
import nrrd
import numpy as np
import pytest

from hwsim.cli.commands import main

pytestmark = pytest.mark.system

GiB = 1 << 30


def _npy_claiming(path, shape, dtype="<f8"):
    header = {"descr": dtype, "fortran_order": False, "shape": shape}
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(fh, header)
        fh.write(b"\0" * 64)


def _nifti_claiming(path, shape):
    image = nib.Nifti1Image(np.zeros((2, 2, 2), dtype=np.uint8), np.eye(4))
    image.header.set_data_shape(shape)
    with open(path, "wb") as fh:
        fh.write(image.header.binaryblock + b"\0" * 4)  # 348-byte header + extension flag


def _nrrd(path, sizes, payload: bytes, encoding="raw", extra=""):
    text = (
        f"NRRD0004\ntype: uint8\ndimension: {len(sizes)}\n"
        f"sizes: {' '.join(map(str, sizes))}\nencoding: {encoding}\n"
        + (f"{extra}\n" if extra else "")
        + "\n"
    )
    path.write_bytes(text.encode() + payload)


def _gzip_bomb(nbytes: int) -> bytes:
    """``nbytes`` of zeros, gzip-compressed (about 1000:1), without holding them."""
    z = zlib.compressobj(9, zlib.DEFLATED, zlib.MAX_WBITS | 16)
    block = b"\0" * (1 << 20)
    return b"".join(z.compress(block) for _ in range(nbytes >> 20)) + z.flush()


def _cases(tmp):
    """(file, fragment the message must hold) for each hostile input."""
    cases = []
    p = tmp / "lying.npy"
    _npy_claiming(p, (2000, 2000, 2000))
    cases.append((p, "memory budget"))
    p = tmp / "short.npy"
    _npy_claiming(p, (8, 8, 8), "<u1")  # 64 bytes written, 512 declared
    cases.append((p, "header declares"))
    p = tmp / "lying.nii"
    _nifti_claiming(p, (1024, 1024, 1024))  # the 416-byte NIfTI that once reached 1.1 GB
    cases.append((p, "header describes 1073741824"))
    p = tmp / "short.nii"
    _nifti_claiming(p, (8, 8, 8))
    cases.append((p, "header describes"))
    nrrds = [  # name, sizes, payload, encoding, fragment
        ("bomb", (64, 64, 64), _gzip_bomb(64 << 20), "gzip", "more than 262144"),  # 64 MiB in
        ("bigclaim", (4096,) * 3, gzip.compress(b"\0" * 100), "gzip", "memory budget"),
        ("short-gzip", (8, 8, 8), gzip.compress(b"\0" * 100), "gzip", "100 bytes"),
        ("short-bz2", (8, 8, 8), bz2.compress(b"\0" * 100), "bzip2", "100 bytes"),
        ("long-bz2", (8, 8, 8), bz2.compress(b"\0" * 10_000), "bzip2", "more than 512"),
        ("damaged", (8, 8, 8), b"\x1f\x8b\x08\x00garbage-not-deflate" * 4, "gzip", "damaged"),
        ("short", (8, 8, 8), b"\0" * 500, "raw", "500 bytes"),
    ]
    for name, sizes, payload, encoding, fragment in nrrds:
        p = tmp / f"{name}.nrrd"
        _nrrd(p, sizes, payload, encoding)
        cases.append((p, fragment))
    p = tmp / "detached.nhdr"
    _nrrd(p, (8, 8, 8), b"", extra="data file: missing.raw")
    cases.append((tmp / "missing.raw", "data file: file not found"))
    p = tmp / "zero.nrrd"
    _nrrd(p, (8, 8, 8), b"\0" * 512, extra="spacings: 1 0 1")
    cases.append((p, "zero or infinite"))
    for name, spacing in (("tiny", "1e-300 1 1"), ("huge", "1e300 1 1"), ("aniso", "1e-5 1 1")):
        p = tmp / f"{name}.nrrd"
        _nrrd(p, (8, 8, 8), b"\0" * 512, extra=f"spacings: {spacing}")
        cases.append((p, "spacing"))
    p = tmp / "picture.nrrd"
    p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 64)
    cases.append((p, "NRRD"))
    p = tmp / "text.npy"
    p.write_text("hello, not numpy")
    cases.append((p, ".npy"))
    p = tmp / "nan.npy"
    np.save(p, np.full((4, 4, 4), np.nan, dtype=np.float32))
    cases.append((p, "NaN"))
    return cases


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    return _cases(tmp_path_factory.mktemp("hostile"))


def test_every_hostile_file_is_one_exit_2_line(corpus, capsys, tmp_path):
    for path, fragment in corpus:
        volume = path if path.name != "missing.raw" else path.with_name("detached.nhdr")
        argv = ["render", "--volume", str(volume), "--out", str(tmp_path / "o"), "--quiet"]
        assert main(argv) == 2, path
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("hwsim: error: "), (path, err)
        assert str(path) in err and fragment in err, (path, err)


def test_negative_spacing_is_its_magnitude(tmp_path):
    from hwsim.volumes import read_volume

    path = tmp_path / "flipped.nrrd"
    nrrd.write(str(path), np.zeros((3, 4, 5), np.uint8), {"spacings": [-0.5, 2.0, -1.5]})
    assert read_volume(path).spacing == (1.5, 2.0, 0.5)  # (z, y, x), never 1.0


def test_dicom_series_with_a_gap_is_refused(tmp_path, capsys):
    pydicom = pytest.importorskip("pydicom")
    from pydicom.dataset import FileMetaDataset
    from pydicom.uid import ExplicitVRLittleEndian, generate_uid

    series = generate_uid()
    for i, z in enumerate([0.0, 1.0, 2.0, 5.0]):  # a gap of 3 mm among 1 mm slices
        ds = pydicom.Dataset()
        ds.file_meta = FileMetaDataset()
        ds.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
        ds.file_meta.MediaStorageSOPClassUID = "1.2.840.10008.5.1.4.1.1.2"
        ds.file_meta.MediaStorageSOPInstanceUID = generate_uid()
        ds.SOPClassUID, ds.SOPInstanceUID = ds.file_meta.MediaStorageSOPClassUID, generate_uid()
        ds.SeriesInstanceUID, ds.Modality, ds.InstanceNumber = series, "CT", i + 1
        ds.Rows = ds.Columns = 4
        ds.BitsAllocated, ds.BitsStored, ds.HighBit, ds.PixelRepresentation = 16, 16, 15, 1
        ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
        ds.ImagePositionPatient = [0.0, 0.0, z]
        ds.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
        ds.PixelSpacing = [1.0, 1.0]
        ds.PixelData = np.zeros((4, 4), np.int16).tobytes()
        (tmp_path / "series").mkdir(exist_ok=True)
        ds.save_as(tmp_path / "series" / f"s{i}.dcm", enforce_file_format=True)
    volume = str(tmp_path / "series")  # the output beside it: never inside an input
    assert main(["render", "--volume", volume, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "not evenly spaced" in err and "ImagePositionPatient" in err and err.count("\n") == 1


def test_lying_headers_stay_far_below_1_gib(corpus, tmp_path):
    """Peak memory of a child reading every lying header: a resource check, not a timing."""
    lying = [
        str(p)
        for p, fragment in corpus
        if fragment in ("memory budget", "more than 262144", "header describes 1073741824")
    ]
    assert len(lying) == 4
    # The child reports its own peak, VmHWM (this process image's high-water mark, reset
    # by exec): RUSAGE_CHILDREN is the largest of every child this worker waited for, and
    # a child's ru_maxrss keeps the size of the forking worker across exec.
    script = (
        "import sys\nfrom hwsim.cli.commands import main\n"
        "for p in sys.argv[2:]:\n"
        "    argv = ['render', '--volume', p, '--out', sys.argv[1], '--quiet']\n"
        "    assert main(argv) == 2\n"
        "status = open('/proc/self/status').read()\n"
        "print(status.split('VmHWM:')[1].split()[0])\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "HWSIM_MAX_MEMORY"}
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "o"), *lying],
        capture_output=True,
        text=True,
        env=env,
    )
    assert done.returncode == 0, done.stderr
    peak_kib = int(done.stdout.split()[-1])
    assert peak_kib * 1024 < GiB // 2, f"peak {peak_kib / 1024:.0f} MiB"
