"""VolumePro 500's hardware 3-D cursor (VLI's VLICursor) at every rung (issue 16)."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
import rungs
from hypothesis import given
from hypothesis import strategies as st

from hwsim.core.errors import InputError
from hwsim.golden.cursor import blend_cursor, cursor_parts
from hwsim.numerics import psnr
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import CropSpec, parse_scene
from hwsim.spec.scene_cursor import CursorAxis, CursorSpec
from hwsim.volumes import make_phantom
from models.units.cursor import CursorTable

pytestmark = pytest.mark.model

SIZE = 24


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=SIZE)


def _grid(n: int) -> np.ndarray:
    """Every integer (z, y, x) position of an n^3 volume."""
    return np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3) * 1.0


@pytest.mark.parametrize("width", [1, 3, 5, 7])
def test_a_crosshair_bar_is_width_squared_voxels_thick(width):
    cursor = CursorSpec(position=(8.0, 9.0, 10.0), width=width, length=6.0)
    part = cursor_parts(_grid(20), cursor)
    # Along x: |dx| <= 3 (7 voxels), w x w across; y and z likewise; the three bars
    # share their w^3 core, which goes to x (the first axis).
    core = width**3
    assert np.sum(part == 0) == 7 * width**2
    assert np.sum(part == 1) == 7 * width**2 - core
    assert np.sum(part == 2) == 7 * width**2 - core


def test_a_plane_cursor_and_its_options():
    n = 16
    grid = _grid(n)
    plane = CursorSpec(type="plane", position=(4.0, 5.0, 6.0), width=1)
    part = cursor_parts(grid, plane)
    assert np.sum(part == 0) == n * n  # the plane x = 4
    assert np.all(grid[part == 0][:, 2] == 4.0)
    off = CursorSpec(
        type="plane", position=(4.0, 5.0, 6.0), x=CursorAxis(color=(1, 0, 0), enabled=False)
    )
    assert np.sum(cursor_parts(grid, off) == 0) == 0
    excluded = dataclasses.replace(plane, exclude_overlap=True)
    lines = (grid[:, 2] == 4.0).astype(int) + (grid[:, 1] == 5.0) + (grid[:, 0] == 6.0)
    assert np.array_equal(cursor_parts(grid, excluded) >= 0, lines == 1)


@given(
    colour=st.lists(st.floats(0, 1), min_size=4, max_size=4),
    rgb=st.lists(st.integers(0, 4096), min_size=3, max_size=3),
    alpha=st.integers(0, 4096),
)
def test_the_unit_blend_is_the_float_blend_within_its_bound(colour, rgb, alpha):
    axis = CursorAxis(color=tuple(colour[:3]), opacity=colour[3])
    cursor = CursorSpec(x=axis)
    table = CursorTable(cursor)
    part = np.array([0], dtype=np.int8)
    got_rgb, got_a = table.blend(np.array([rgb]), np.array([alpha]), part)
    want_rgb, want_a = blend_cursor(np.array([rgb]) / 4096, np.array([alpha]) / 4096, part, cursor)
    # 8-bit colour and opacity (2**-9 each, the opacity's error scaled by |c - x| <= 1)
    # plus one UQ1.12 rounding.
    bound = 2 * 2.0**-9 + 2.0**-13
    assert np.all(np.abs(got_rgb / 4096 - want_rgb) <= bound)
    assert np.all(np.abs(got_a / 4096 - want_a) <= bound)
    assert got_rgb.max() <= 4096 and got_a.max() <= 4096


def test_an_opaque_cursor_replaces_the_sample_and_a_clear_one_leaves_it():
    opaque = CursorTable(CursorSpec(x=CursorAxis(color=(0.2, 0.4, 1.0), opacity=1.0)))
    clear = CursorTable(CursorSpec(x=CursorAxis(color=(0.2, 0.4, 1.0), opacity=0.0)))
    rgb, alpha, on = np.array([[100, 2000, 4096]]), np.array([1234]), np.array([0], np.int8)
    got_rgb, got_a = opaque.blend(rgb, alpha, on)
    assert got_rgb.tolist() == [opaque.rgba[0, :3].tolist()] and got_a.tolist() == [4096]
    got_rgb, got_a = clear.blend(rgb, alpha, on)
    assert got_rgb.tolist() == rgb.tolist() and got_a.tolist() == [1234]


def _with_cursor(scene, **changes):
    c = SIZE / 2
    cursor = CursorSpec(position=(c, c, c), width=3, length=SIZE * 0.8, **changes)
    return scene.replace(cursor=cursor)


def test_the_cursor_on_volumepro_500_at_every_rung(head):
    """As built: the cycle image is the functional image bit for bit, the cursor costs
    no cycles, the transaction rung stays within its contract and golden agrees to the
    datapath's precision; the cursor changes the image."""
    plain = rungs.scene_of(35, 25, size=2 * SIZE)
    scene = _with_cursor(plain, y=CursorAxis(color=(0, 1, 0), opacity=0.5))
    fixed, cycle, _ = rungs.functional_and_cycle(scene, head, "volumepro500")
    rungs.assert_identical(fixed, cycle)
    exact, approx = rungs.within_contract(scene, head, "volumepro500")
    bare, bare_cycle, _ = rungs.functional_and_cycle(plain, head, "volumepro500")
    assert cycle.cycles == bare_cycle.cycles
    assert np.sum(np.abs(fixed.image - bare.image).max(axis=-1) > 0.05) > 20
    gold = render(scene, fidelity="golden", arch=resolve_arch("volumepro500"), volume=head)
    assert psnr(fixed.image, gold.image) > 50.0


@pytest.mark.parametrize("disable_crop", [True, False])
def test_disable_crop_draws_the_cursor_where_the_volume_is_cut_away(head, disable_crop):
    # A crop that keeps nothing of the head (x beyond the volume).
    plain = rungs.scene_of(35, 25, size=SIZE, crop=CropSpec(x=(500.0, 600.0)))
    scene = _with_cursor(plain, disable_crop=disable_crop)
    arch = resolve_arch("volumepro500")
    for rung in ("golden", "functional", "cycle"):
        image = render(scene, fidelity=rung, arch=arch, volume=head).image
        assert (image.max() > 0.5) == disable_crop, rung


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ("[cursor]\nposition = [1, 2, 3]\nwidth = 2", "cursor.width"),
        ("[cursor]\nposition = [1, 2, 3]\ntype = 'box'", "cursor.type"),
        ("[cursor]\nwidth = 3", "cursor.position"),
        ("[cursor]\nposition = [1, 2, 3]\n[cursor.x]\nopacity = 1.5", "cursor.x.opacity"),
        ("[render]\nmode = 'mip'\n[cursor]\nposition = [1, 2, 3]", "render.mode"),
    ],
)
def test_a_malformed_cursor_is_refused_naming_the_key(table, key):
    from hwsim.spec.scene_features import check_features

    with pytest.raises(InputError) as info:
        check_features(parse_scene(tomllib.loads(table), source="s.toml"))
    assert info.value.key == key


def test_machines_without_the_cursor_refuse_it(head):
    scene = _with_cursor(rungs.scene_of(35, 25, size=SIZE))
    with pytest.raises(InputError) as info:
        render(scene, fidelity="cycle", arch=resolve_arch("volumepro1000"), volume=head)
    assert info.value.key == "cursor"
    # VIZARD II leaps empty space: its leaps would skip the cursor, so not even a what-if.
    with pytest.raises(InputError) as info:
        render(scene, fidelity="cycle", arch=resolve_arch("vizard2"), volume=head, extend=True)
    assert info.value.key == "cursor" and "leap" in str(info.value)


def test_the_rtl_top_refuses_the_cursor(head):
    from hwsim.spec.transfer import resolve_transfer
    from models.frame import frame_of
    from rtl.frame import prepare

    volume = make_phantom("head", size=12)
    scene = _with_cursor(rungs.scene_of(35, 25, size=12))
    tf = resolve_transfer(scene.transfer, volume)
    with pytest.raises(InputError) as info:
        prepare(frame_of(scene, volume, tf, resolve_arch("cube4")))
    assert info.value.key == "cursor"
