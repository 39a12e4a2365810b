"""Phantoms: closed forms (ball chords, Marschner-Lobb values), the head's anatomy in HU,
determinism, and the NAME:key=value spec parser."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.volumes import PHANTOMS, make_phantom, marschner_lobb, parse_phantom_spec
from hwsim.volumes.phantoms import BALL_SUBSAMPLES, ML_ALPHA, ML_FM

# --------------------------------------------------------------------------- ball


def chords(n: int, r: float, footprint: int = 1) -> np.ndarray:
    """Chord length 2 sqrt(r^2 - d^2) through each pixel of an (n, n) projection, d from
    the centre (n-1)/2; averaged over a ``footprint`` x ``footprint`` grid in the pixel."""
    sub = (np.arange(footprint) + 0.5) / footprint - 0.5
    t = np.arange(n) - (n - 1) / 2.0
    a = (t[:, None] + sub[None, :])[:, None, :, None]
    b = (t[:, None] + sub[None, :])[None, :, None, :]
    return (2.0 * np.sqrt(np.maximum(r * r - a * a - b * b, 0.0))).mean(axis=(2, 3))


@pytest.mark.parametrize("n", [32, 33, 64])
def test_ball_xray_along_x_matches_the_chord_length(n):
    """Sum along x / value = 2 sqrt(r^2 - d^2) to within 0.02 voxel for rays with
    d <= r/2; everywhere, the chord averaged over the pixel's 1 x 1 footprint to within
    0.06 voxel (exactly, for the footprint quadrature the phantom itself uses)."""
    value = 200.0
    ball = make_phantom("ball", size=n, dtype="float64", value=value)
    r = 0.8 * n / 2
    assert ball.meta["radius_vox"] == pytest.approx(r)
    assert ball.meta["centre"] == ((n - 1) / 2,) * 3
    xray = ball.data.sum(axis=2) / value  # (z, y)
    t = np.arange(n) - (n - 1) / 2
    d = np.hypot(t[:, None], t[None, :])
    centre_line = chords(n, r)
    assert np.abs(xray - centre_line)[d <= r / 2].max() < 0.02
    assert np.abs(xray - chords(n, r, footprint=32)).max() < 0.06
    np.testing.assert_allclose(xray, chords(n, r, footprint=BALL_SUBSAMPLES), atol=1e-9)
    if n % 2:  # odd sizes have a ray through the centre: the diameter
        assert xray[n // 2, n // 2] == pytest.approx(2 * r, abs=0.02)


def test_ball_xray_along_the_other_axes_within_the_subsample_step():
    n, r = 48, 0.8 * 24
    ball = make_phantom("ball", size=n, dtype="float64", value=1.0)
    reference = chords(n, r, footprint=32)
    for axis in (0, 1):
        err = np.abs(ball.data.sum(axis=axis) - reference).max()
        assert err < 1.0 / BALL_SUBSAMPLES


def test_ball_volume_edges_and_integer_rounding():
    ball = make_phantom("ball", size=40, radius=0.5, value=100, dtype="uint16")
    r = 0.5 * 20
    assert ball.data.dtype == np.uint16 and ball.bits == 16 and ball.units == ""
    assert ball.data.sum() / 100 == pytest.approx(4 / 3 * np.pi * r**3, rel=2e-3)
    assert ball.data[20, 20, 20] == 100 and ball.data[0, 0, 0] == 0
    edge = ball.data[(ball.data > 0) & (ball.data < 100)]
    assert edge.size > 0  # partial-volume voxels exist
    np.testing.assert_array_equal(ball.data, ball.data[::-1, ::-1, ::-1])  # centred
    assert ball.name == "ball" and ball.source == "ball:size=40,radius=0.5,value=100,dtype=uint16"


def test_ball_full_radius_fits_the_box_and_size_one_works():
    big = make_phantom("ball", size=16, radius=1.0, dtype="float32", value=1.0)
    assert big.data.sum() == pytest.approx(4 / 3 * np.pi * 8**3, rel=3e-3)
    tiny = make_phantom("ball", size=1)
    assert tiny.shape == (1, 1, 1) and tiny.data[0, 0, 0] > 0


# --------------------------------------------------------------------------- Marschner-Lobb


def test_marschner_lobb_known_values():
    assert marschner_lobb(0, 0, -1) == pytest.approx(1.0)
    assert marschner_lobb(0, 0, 1) == pytest.approx(0.2)
    assert marschner_lobb(0, 0, 0) == pytest.approx(0.6)
    # the radial term uses r = sqrt(x^2 + y^2) only: z does not enter it
    expected = ((1 - np.sin(np.pi / 4)) + ML_ALPHA * 2) / (2 * (1 + ML_ALPHA))
    assert marschner_lobb(0, 0, 0.5) == pytest.approx(expected)
    # where cos(pi r / 2) = 1 / (2 f_M), rho_r = cos(pi) = -1 and the radial term vanishes
    r0 = 2 / np.pi * np.arccos(1 / (2 * ML_FM))
    assert marschner_lobb(r0 * 0.6, r0 * 0.8, 0) == pytest.approx(1 / (2 * (1 + ML_ALPHA)))
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1, 1, size=(3, 10000))
    values = marschner_lobb(*pts)
    assert values.shape == (10000,) and values.min() >= 0 and values.max() <= 1


def test_marschner_lobb_lattice_and_spacing():
    n = 40
    vol = make_phantom("marschner-lobb")
    assert vol.shape == (n, n, n) and vol.data.dtype == np.float32 and vol.bits == 0
    assert vol.spacing == pytest.approx((2 / 39,) * 3)
    axis = np.linspace(-1, 1, n)
    k = 17
    z, y, x = axis[k], axis[5], axis[31]
    assert vol.data[k, 5, 31] == pytest.approx(marschner_lobb(x, y, z), abs=1e-6)
    assert vol.data[0, 20, 20] == pytest.approx(marschner_lobb(axis[20], axis[20], -1.0), abs=1e-6)
    zz, yy, xx = np.meshgrid(axis, axis, axis, indexing="ij")
    np.testing.assert_allclose(vol.data, marschner_lobb(xx, yy, zz), atol=1e-6)


def test_marschner_lobb_integer_types_use_full_scale():
    vol8 = make_phantom("marschner-lobb", size=9, dtype="uint8")
    vol16 = make_phantom("marschner-lobb", size=9, dtype="uint16")
    exact = make_phantom("marschner-lobb", size=9, dtype="float64").data
    np.testing.assert_array_equal(vol8.data, np.rint(exact * 255))
    np.testing.assert_array_equal(vol16.data, np.rint(exact * 65535))
    assert vol8.bits == 8 and vol16.bits == 16 and vol8.meta["scale"] == 255


# --------------------------------------------------------------------------- head


def at(vol, x: float, y: float, z: float) -> int:
    """Voxel at normalised head coordinates (each -1 .. 1 across the box)."""
    n = vol.shape[2]
    half = n / 2
    iz = round(z * half / vol.spacing[0] + (vol.shape[0] - 1) / 2)
    return int(vol.data[iz, round(y * half + (n - 1) / 2), round(x * half + (n - 1) / 2)])


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=96, noise=0)


@pytest.mark.parametrize(
    ("where", "lo", "hi"),
    [
        ((0.95, 0.95, 0.95), -1000, -1000),  # air
        ((0.45, 0.3, 0.0), 35, 35),  # brain (grey)
        ((0.0, 0.22, 0.05), 28, 28),  # white matter
        ((0.1, 0.24, 0.05), 5, 5),  # ventricle (CSF)
        ((0.26, -0.1, -0.59), 12, 12),  # eyeball
        ((0.0, -0.3, -0.5), -1000, -1000),  # maxillary sinus
        ((0.0, -0.6, 0.3), 300, 300),  # spinal marrow
        ((0.0, -0.6, 0.2), 30, 50),  # neck soft tissue
    ],
)
def test_head_tissues_in_the_right_places(head, where, lo, hi):
    assert lo <= at(head, *where) <= hi


def test_head_skull_scalp_and_ranges(head):
    n = head.shape[1]
    column = head.data[:, :, n // 2]  # the midline (z, y) plane
    top = column[(n - 1) // 2 + 1, :]  # along y through the crown
    crown = top[int(n * 0.85) :]  # from y ~ 0.7 up
    assert 700 <= crown.max() <= 1500  # the skull
    scalp = crown[np.argmax(crown) :]
    assert np.any((scalp >= 30) & (scalp <= 50))  # skin outside the bone
    assert head.units == "HU" and head.data.dtype == np.int16 and head.bits == 16
    assert head.data.min() == -1000 and head.data.max() <= 2000
    assert head.value_range == (-1024, 3071)  # declared: the 12-bit CT window it is clipped to
    bone = head.data >= 700
    assert 0.02 < bone.mean() < 0.15


def test_head_is_deterministic_for_a_seed_and_noise_is_mild():
    a = make_phantom("head", size=32, seed=3)
    b = make_phantom("head", size=32, seed=3)
    c = make_phantom("head", size=32, seed=4)
    clean = make_phantom("head", size=32, noise=0)
    np.testing.assert_array_equal(a.data, b.data)
    assert not np.array_equal(a.data, c.data)
    diff = a.data.astype(float) - clean.data
    air = clean.data == -1000
    assert 6 < diff[~air].std() < 10  # default 8 HU
    assert a.source == "head:size=32,seed=3"


def test_head_noise_is_standard_normal_and_independent_of_the_box():
    from hwsim.volumes.phantoms import gaussian_noise

    shape = (40, 50, 60)
    whole = gaussian_noise(7, shape, range(0, 40), range(0, 50))
    assert abs(whole.mean()) < 0.01 and abs(whole.std() - 1.0) < 0.01
    assert abs(np.corrcoef(whole[:, :, :-1].ravel(), whole[:, :, 1:].ravel())[0, 1]) < 0.01
    part = gaussian_noise(7, shape, range(11, 12), range(20, 37))
    np.testing.assert_array_equal(part, whole[11:12, 20:37])
    assert not np.array_equal(gaussian_noise(8, shape, range(0, 40), range(0, 50)), whole)


@pytest.mark.parametrize("z_spacing", [1.0, 1.5])
@pytest.mark.parametrize(
    "box", [(5, 6, 0, 48), (0, 32, 7, 8), (3, 30, 10, 40), (31, 32, 47, 48)], ids=str
)
def test_a_box_of_the_head_is_the_wholes_bits(box, z_spacing):
    """What a worker generating only its part of the phantom relies on."""
    from hwsim.volumes.phantoms import head_box

    whole = make_phantom("head", size=48, seed=5, z_spacing=z_spacing).data
    z0, z1, y0, y1 = box
    part = head_box(48, 8.0, 5, z_spacing, slice(z0, z1), slice(y0, y1))
    np.testing.assert_array_equal(part, whole[z0:z1, y0:y1])


def test_head_anisotropic_slices_keep_the_anatomy():
    thick = make_phantom("head", size=64, noise=0, z_spacing=2.0)
    assert thick.shape == (32, 64, 64) and thick.spacing == (2.0, 1.0, 1.0)
    assert at(thick, 0.45, 0.3, 0.0) == 35 and at(thick, 0.95, 0.95, 0.9) == -1000


# --------------------------------------------------------------------------- spec and params


def test_parse_phantom_spec():
    assert parse_phantom_spec("head:size=64,noise=0") == ("head", {"size": 64, "noise": 0.0})
    assert parse_phantom_spec("ball") == ("ball", {})
    assert parse_phantom_spec(" ball : radius=0.5 , dtype=float32 ") == (
        "ball",
        {"radius": 0.5, "dtype": "float32"},
    )
    name, params = parse_phantom_spec("marschner-lobb:size=12")
    assert make_phantom(name, **params).shape == (12, 12, 12)


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("teapot", "unknown phantom 'teapot' (allowed: ball, marschner-lobb, head)"),
        ("ball:size", "expected key=value"),
        ("ball:size=", "expected key=value"),
        ("ball:size=abc", "size: must be int, got 'abc' (allowed: 1 .. 1024)"),
        ("ball:size=2.5", "must be int"),
        ("ball:colour=red", "unknown parameter 'colour' (allowed: size, radius, value, dtype)"),
        ("ball:size=4,size=5", "given twice"),
        ("ball:size=0", "size: 0 is out of range (allowed: 1 .. 1024)"),
        ("ball:dtype=int32", "allowed: uint8, int8, uint16, int16, float32, float64"),
        ("head:noise=nan", "noise: nan is out of range"),
    ],
)
def test_parse_phantom_spec_rejects(text, needle):
    with pytest.raises(InputError) as exc:
        parse_phantom_spec(text)
    assert needle in str(exc.value)


@pytest.mark.parametrize(
    ("name", "params", "needle"),
    [
        ("cube", {}, "unknown phantom 'cube'"),
        ("ball", {"size": 2000}, "ball:size=2000: size: 2000 is out of range (allowed: 1 .. 1024)"),
        ("ball", {"value": 300}, "value: 300 does not fit uint8 (allowed: 0 .. 255)"),
        ("ball", {"radius": 0}, "radius: 0.0 is out of range"),
        ("ball", {"size": True}, "must be int"),
        ("marschner-lobb", {"size": 1}, "(allowed: 2 .. 1024)"),
        ("head", {"z_spacing": 10}, "z_spacing"),
        ("head", {"smoothness": 1}, "unknown parameter 'smoothness'"),
    ],
)
def test_make_phantom_rejects(name, params, needle):
    with pytest.raises(InputError) as exc:
        make_phantom(name, **params)
    assert needle in str(exc.value)


def test_phantom_listing_has_descriptions_and_defaults():
    assert list(PHANTOMS) == ["ball", "marschner-lobb", "head"]
    for name, info in PHANTOMS.items():
        text = str(info)
        assert info.description in text and "size=" in text
        vol = make_phantom(name, size=8 if name != "marschner-lobb" else 5)
        assert vol.name == name and vol.source.startswith(name + ":")
        assert vol.bits == (0 if vol.data.dtype.kind == "f" else vol.data.dtype.itemsize * 8)
    assert PHANTOMS["ball"].defaults == {
        "size": 64,
        "radius": 0.8,
        "value": 200.0,
        "dtype": "uint8",
    }


def test_docs_python_example_runs():
    """The ```python block of docs/volumes.md runs as written."""
    docs = Path(__file__).resolve().parents[2] / "docs" / "volumes.md"
    (example,) = re.findall(r"```python\n(.*?)```", docs.read_text(), flags=re.S)
    exec(compile(example, str(docs), "exec"), {})
