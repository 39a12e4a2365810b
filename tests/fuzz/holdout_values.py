"""Hold-out cases (issue 33), two classes of bad input: environment values
(``HWSIM_*``) and volume formats (NRRD headers, NumPy arrays, NIfTI files, suffixes that
lie).  Listed in :data:`CASES`, in order."""

from __future__ import annotations

import gzip

import numpy as np
from holdout_files import RENDER, Case, _file, _nrrd, _volume, registrar

CASES: list[Case] = []
case = registrar(CASES)


# ------------------------------------------------------------------ environment


@case("env")
def env_threads_hex(d):
    return RENDER, [], {"HWSIM_THREADS": " 0x10"}


@case("env")
def env_memory_negative(d):
    return RENDER, [], {"HWSIM_MAX_MEMORY": "-5G"}


@case("env")
def env_samples_overflow(d):
    return RENDER, [], {"HWSIM_MAX_SAMPLES": "1e400"}


@case("env")
def env_debug_word(d):
    return RENDER, [], {"HWSIM_DEBUG": "maybe"}


@case("env")
def env_rtl_build_a_file(d):
    f = _file(d, "f", "x")
    return RENDER, [f], {"HWSIM_RTL_BUILD": str(f)}


@case("env")
def env_memory_tiny(d):
    return RENDER, [], {"HWSIM_MAX_MEMORY": "1K"}


@case("env", expect="either")
def env_threads_other_digits(d):
    return RENDER, [], {"HWSIM_THREADS": "\u0661\u0662"}  # Arabic-Indic 12


# ------------------------------------------------------------------ formats


@case("formats")
def nrrd_gzip_of_raw_bytes(d):
    v = _nrrd(d, "type: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: gzip")
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nrrd_sizes_short(d):
    v = _nrrd(d, "type: uint8\ndimension: 3\nsizes: 4 4\nencoding: raw")
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nrrd_middle_endian(d):
    v = _nrrd(d, "type: short\ndimension: 3\nsizes: 4 4 2\nendian: middle\nencoding: raw")
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nrrd_space_directions_garbage(d):
    header = "type: uint8\ndimension: 3\nsizes: 4 4 4\nspace directions: (a,b,c) x y\nencoding: raw"
    v = _nrrd(d, header)
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def npy_two_dimensional(d):
    v = _volume(d, shape=(4, 4))
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats", expect="either")
def npy_bool_volume(d):
    v = _volume(d, dtype=bool)
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nifti_truncated(d):
    import nibabel

    full = d / "full.nii"
    nibabel.save(nibabel.Nifti1Image(np.zeros((4, 4, 4), np.uint8), np.eye(4)), full)
    v = _file(d, "v.nii", full.read_bytes()[:200])
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def unknown_suffix(d):
    v = _file(d, "v.raw", bytes(64))
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nii_gz_not_gzip(d):
    v = _file(d, "v.nii.gz", b"\x1f\x8b" + bytes(100))
    return ["convert", str(v), "o.npy"], [v]


@case("formats")
def npy_gzip_named_npy(d):
    v = _file(d, "v.npy", gzip.compress(bytes(100)))
    return ["convert", str(v), "o.nrrd"], [v]
