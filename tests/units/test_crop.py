"""Crop box and cut planes against the golden float64 versions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.golden import shading
from hwsim.spec.scene import CropSpec, CutPlane
from models.units import crop as cr

pytestmark = pytest.mark.model


CROPS = [
    CropSpec(x=(10.0, 40.0)),
    CropSpec(x=(10.3, 40.7), y=(0.0, 20.0), z=(5.5, 5.5)),
    CropSpec(y=(3.0, 60.0), invert=True),
    CropSpec(x=(0.0, 63.0), y=(0.0, 63.0), z=(0.0, 63.0), invert=True),
    CropSpec(),
    CropSpec(x=(10.0, 40.0), y=(5.0, 30.5), z=(20.0, 50.0), mode="cross"),
    CropSpec(x=(10.0, 40.0), y=(5.0, 30.5), z=(20.0, 50.0), mode="fence", invert=True),
    CropSpec(x=(10.0, 40.0), y=(5.0, 30.5), mode="cross", invert=True),
]


#: VTK's cropping-region flags (vtkVolumeMapper.h): bit ``x + 3 y + 9 z`` set when the
#: region (each axis 0 below, 1 inside, 2 above its slab) is kept.
VTK_FLAGS = [
    ("subvolume", False, 0x0002000),
    ("fence", False, 0x2EBFEBA),
    ("fence", True, 0x5140145),
    ("cross", False, 0x0417410),
    ("cross", True, 0x7BE8BEF),
]


@pytest.mark.parametrize(("mode", "invert", "flags"), VTK_FLAGS)
def test_crop_modes_keep_the_regions_vtk_names(mode: str, invert: bool, flags: int) -> None:
    crop = CropSpec(x=(10.0, 20.0), y=(10.0, 20.0), z=(10.0, 20.0), mode=mode, invert=invert)
    centre = {0: 5.0, 1: 15.0, 2: 25.0}  # below, inside, above each slab
    regions = [(x, y, z) for z in range(3) for y in range(3) for x in range(3)]
    zyx = np.array([[centre[z], centre[y], centre[x]] for x, y, z in regions])
    want = np.array([bool(flags >> (x + 3 * y + 9 * z) & 1) for x, y, z in regions])
    assert (shading.crop_keep(zyx, crop) == want).all()
    raw = (zyx * 16).astype(np.int64)
    assert (cr.crop_keep(raw, crop, 4) == want).all()


@pytest.mark.parametrize("crop", CROPS)
def test_crop_float_matches_golden(crop: CropSpec, rng: np.random.Generator) -> None:
    zyx = rng.uniform(-2, 66, (5000, 3))
    zyx[:100] = np.round(zyx[:100])  # hit the inclusive limits exactly
    assert (cr.crop_keep(zyx, crop) == shading.crop_keep(zyx, crop)).all()


@given(st.integers(1, 12), st.integers(0, 2**31 - 1))
@settings(deadline=None, max_examples=100)
def test_crop_fixed_matches_golden_exactly(frac_bits: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    raw = rng.integers(-4 << frac_bits, 70 << frac_bits, (2000, 3))
    lo, hi = np.sort(rng.uniform(0, 64, 2))
    mode = ("subvolume", "cross", "fence")[seed % 3]
    crop = CropSpec(x=(lo, hi), z=(float(np.floor(lo)), 50.0), invert=bool(seed & 4), mode=mode)
    zyx = raw / 2.0**frac_bits  # exact in float64
    assert (cr.crop_keep(raw, crop, frac_bits) == shading.crop_keep(zyx, crop)).all()


PLANES = [
    CutPlane(normal=(0.0, 0.0, 1.0), offset=0.0, thickness=10.0, falloff=5.0),
    CutPlane(normal=(1.0, 2.0, 3.0), offset=7.25, thickness=3.0, falloff=20.0),
    CutPlane(normal=(-1.0, 0.5, 0.1), offset=-30.0, thickness=0.0, falloff=0.5, invert=True),
    CutPlane(normal=(0.3, -0.7, 0.2), offset=12.0, thickness=40.0, falloff=100.0),
]


@pytest.mark.parametrize("plane", PLANES)
def test_cut_factor_within_bound(plane: CutPlane, rng: np.random.Generator) -> None:
    p = rng.uniform(-128, 128, (20000, 3))
    got = cr.cut_factor(p, (plane,)) / 4096
    gold = shading.cut_factor(p, (plane,))
    bound = cr.cut_error_bound(p, (plane,))
    assert (np.abs(got - gold) <= bound).all()
    assert got.min() >= 0 and got.max() <= 1


def test_four_planes_vp1000(rng: np.random.Generator) -> None:
    cfg = cr.CutConfig(max_planes=4)
    p = rng.uniform(-100, 100, (20000, 3))
    got = cr.cut_factor(p, tuple(PLANES[:2] + PLANES[3:]), cfg) / 4096
    gold = shading.cut_factor(p, tuple(PLANES[:2] + PLANES[3:]))
    assert (np.abs(got - gold) <= cr.cut_error_bound(p, tuple(PLANES[:2] + PLANES[3:]), cfg)).all()
    with pytest.raises(ValueError):
        cr.cut_factor(p, tuple(PLANES[:2]))  # VolumePro 500 has one plane


@pytest.mark.extremes
def test_hard_slab_exact_away_from_edge(rng: np.random.Generator) -> None:
    plane = CutPlane(normal=(1.0, 1.0, 0.0), offset=3.0, thickness=8.0, falloff=0.0)
    p = rng.uniform(-128, 128, (50000, 3))
    got = cr.cut_factor(p, (plane,))
    gold = shading.cut_factor(p, (plane,))
    n = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    edge = np.abs(np.abs(p @ n - 3.0) - 4.0)
    far = edge > cr.distance_error_bound(p)
    assert set(np.unique(got)) <= {0, 4096}
    assert (got[far] == gold[far] * 4096).all()
    assert far.mean() > 0.99


@pytest.mark.extremes
def test_extreme_positions_saturate_not_wrap() -> None:
    plane = CutPlane(normal=(0.0, 0.0, 1.0), offset=0.0, thickness=2.0, falloff=1.0)
    p = np.array([[0.0, 0.0, 1e6], [0.0, 0.0, -1e6], [0.0, 0.0, 0.0]])
    assert cr.cut_factor(p, (plane,)).tolist() == [0, 0, 4096]
    with pytest.raises(ValueError):
        cr.cut_factor(p, (CutPlane(normal=(0.0, 0.0, 0.0)),))
