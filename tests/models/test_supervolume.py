"""Supervolumes (issue 16): a volume over a machine's one-pass limit, rendered in bricks
and blended on the host, bit-exact between the rungs that render the same bricks."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import rungs
from hypothesis import given
from hypothesis import strategies as st

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.golden import make_plan
from hwsim.golden.bricks import HALO, BrickPlan, split_bricks
from hwsim.numerics import psnr
from hwsim.run.fidelity import render, resolve_arch
from hwsim.run.supervolume import blend_unorm, render_bricks
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of
from models.functional import render_functional

pytestmark = pytest.mark.model

SIZE = 28
LIMIT = 16  # bricks of at most 16 voxels: 3 per axis at 28 (cores of 12 + halo)


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=SIZE)


def _machine(name="volumepro500", limit=LIMIT):
    return dataclasses.replace(resolve_arch(name), max_volume=(limit, limit, limit))


@pytest.mark.parametrize("shape", [(28, 28, 28), (40, 17, 9), (16, 16, 16), (100, 33, 70)])
def test_bricks_fit_the_machine_and_their_cores_tile_the_volume(shape):
    bricks = split_bricks(shape, (LIMIT, LIMIT, LIMIT))
    owner = np.zeros(shape, dtype=np.int64)
    for b in bricks:
        assert all(0 < s <= LIMIT for s in b.shape)
        cores = [
            slice(int(max(lo + 0.5, 0)), int(min(hi + 0.5, n)))
            for lo, hi, n in zip(b.core_lo, b.core_hi, shape, strict=True)
        ]
        owner[tuple(cores)] += 1
        # The halo: every owned voxel's neighbours within HALO are in the brick.
        for axis, cut in enumerate(cores):
            assert b.lo[axis] <= max(cut.start - HALO, 0)
            assert b.hi[axis] >= min(cut.stop + HALO, shape[axis])
    assert np.all(owner == 1)


def _samples(plan, to_whole=lambda j, p: (j, p)):
    out = {}
    for j, step in enumerate(plan.steps()):
        jj, zyx = to_whole(j, step.zyx)
        for ray, p in zip(step.rays.tolist(), zyx.tolist(), strict=True):
            out[(ray, tuple(p))] = jj
    return out


@pytest.mark.parametrize(
    ("sampling", "projection", "order"),
    [
        ("shear-warp", "parallel", "front-to-back"),
        ("shear-warp", "parallel", "back-to-front"),
        ("shear-image", "parallel", "front-to-back"),
        ("shear-image", "perspective", "front-to-back"),
    ],
)
def test_the_bricks_own_every_sample_of_the_whole_plan_once(head, sampling, projection, order):
    scene = rungs.scene_of(
        35,
        25,
        size=SIZE,
        projection=projection,
        render={"blend_order": order, "supersampling": 1.5},
    )
    whole = make_plan(scene, head, sampling)
    want = _samples(whole)
    got = {}
    for brick in split_bricks(head.shape, (LIMIT,) * 3):
        part = head.brick(brick.lo, brick.hi, brick.label)
        plan = BrickPlan(whole, brick, part)
        origin = np.asarray(brick.lo, dtype=np.float64)
        mine = _samples(plan, lambda j, p, plan=plan, o=origin: (j + plan.j0, p + o))
        assert not (mine.keys() & got.keys())
        got.update(mine)
        # In the brick's own voxels, away from its faces by less than the halo.
        for _, p in mine:
            local = np.asarray(p) - origin
            assert np.all(local >= -0.5 - 1e-9) and np.all(
                local <= np.asarray(part.shape) - 0.5 + 1e-9
            )
    assert got == want  # the same samples, at the same positions, at the same steps


def test_one_brick_is_the_one_pass_render_bit_for_bit(head):
    scene = rungs.scene_of(35, 25, size=SIZE)
    arch = _machine(limit=SIZE)
    tf = resolve_transfer(scene.transfer, head)
    one = render_functional(frame_of(scene, head, tf, arch))
    bricked = render_bricks(scene, head, tf, arch, render_functional, frame_of)
    assert bricked.derived["supervolume"]["bricks"] == 1
    assert np.array_equal(bricked.image, one.image) and bricked.samples == one.samples


@pytest.mark.parametrize("order", ["front-to-back", "back-to-front"])
@pytest.mark.parametrize("name", ["volumepro500", "em-cube"])
def test_a_supervolume_at_every_rung(head, name, order):
    """Cycle and functional render the same bricks bit for bit; the transaction rung's
    cycles stay within its contract; the frame is the bricks' frames summed; the image is
    the one-pass image up to the host blend's rounding."""
    scene = rungs.scene_of(35, 25, size=SIZE, render={"blend_order": order})
    arch = _machine(name)
    ext = order != "front-to-back" and name == "em-cube"
    runs = {
        r: render(scene, fidelity=r, arch=arch, volume=head, extend=ext or name == "em-cube")
        for r in ("golden", "functional", "transaction", "cycle")
    }
    cycle, fixed = runs["cycle"], runs["functional"]
    assert np.array_equal(cycle.image, fixed.image)
    info = cycle.derived["supervolume"]
    assert info["bricks"] == 27
    assert cycle.cycles == sum(b["cycles"] for b in info["per_brick"])
    rungs.assert_within_contract(cycle.cycles, runs["transaction"].cycles)
    one = render(scene, fidelity="cycle", arch=_machine(name, SIZE), volume=head, extend=ext)
    assert cycle.samples == one.samples and cycle.cycles > one.cycles
    assert psnr(cycle.image, one.image) > 50.0
    assert psnr(cycle.image, runs["golden"].image) > 45.0
    assert (name == "em-cube") == any(e["feature"] == "supervolumes" for e in cycle.extensions)


@pytest.mark.parametrize("mode", ["mip", "minip"])
def test_a_maximum_over_bricks_is_the_one_pass_maximum(head, mode):
    scene = rungs.scene_of(35, 25, size=SIZE, mode=mode)
    bricked = render(scene, fidelity="cycle", arch=_machine(), volume=head)
    one = render(scene, fidelity="cycle", arch=_machine(limit=SIZE), volume=head)
    assert np.array_equal(bricked.image, one.image)


@given(
    front=st.lists(st.integers(0, 255), min_size=4, max_size=4),
    back=st.lists(st.integers(0, 255), min_size=4, max_size=4),
)
def test_the_host_blend_is_the_float_blend_within_one_step(front, back):
    f = np.array([sorted(front[:3]) + [max(front)]])  # premultiplied: colour <= alpha
    b = np.array([sorted(back[:3]) + [max(back)]])
    acc = f.copy()
    blend_unorm(acc, b, 8)
    want = f / 255 + (1 - f[:, 3:] / 255) * b / 255
    assert np.all(np.abs(acc / 255 - want) <= 0.5 / 255 + 1e-12)
    assert acc.max() <= 255
    opaque = np.array([[10, 20, 30, 255]])
    blend_unorm(opaque, b, 8)
    assert opaque.tolist() == [[10, 20, 30, 255]]


def test_what_the_bricks_cannot_model_is_refused(head):
    big = make_phantom("head", size=20)
    scene = rungs.scene_of(35, 25, size=20)
    with pytest.raises(InputError) as info:  # no supervolumes, not opted in
        render(scene, fidelity="cycle", arch=_machine("volumepro1000"), volume=big)
    assert info.value.key == "limits.max_volume"
    run = render(
        scene, fidelity="functional", arch=_machine("volumepro1000"), volume=big, extend=True
    )
    assert [e["feature"] for e in run.extensions] == ["supervolumes"]
    with pytest.raises(InputError) as info:  # a ray-order machine
        render(scene, fidelity="cycle", arch=_machine("vizard2"), volume=big, extend=True)
    assert info.value.key == "pipeline.order"
    xray = rungs.scene_of(35, 25, size=20, mode="xray")
    with pytest.raises(InputError) as info:
        render(xray, fidelity="cycle", arch=_machine("volumepro1000"), volume=big, extend=True)
    assert info.value.key == "render.mode"


def test_the_cli_reports_the_bricks_and_the_host_time(tmp_path):
    arch = tmp_path / "vp500-small.toml"
    text = Path(resolve_arch("volumepro500").source).read_text()
    arch.write_text(text.replace("max_volume = [256, 256, 256]", "max_volume = [16, 16, 16]"))
    out = tmp_path / "out"
    code = main(
        [
            "render",
            "--phantom",
            "head:size=24",
            "--image",
            "24",
            "--arch",
            str(arch),
            "--fidelity",
            "cycle",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    stats = json.loads((out / "stats.json").read_text())
    info = stats["derived"]["supervolume"]
    assert info["bricks"] == 8 and info["host_bytes"] > 0
    machine = stats["cycles"] / stats["clock_hz"]
    assert stats["frame_seconds"] == pytest.approx(machine + info["host_seconds"])


def test_crop_cut_planes_and_the_cursor_stay_where_the_scene_put_them(head):
    """Bricks see their own coordinates; crop, cut planes and the cursor are placed in the
    whole volume, so the bricked image is the one-pass image up to the host blend."""
    from hwsim.spec.scene import CropSpec, CutPlane
    from hwsim.spec.scene_cursor import CursorSpec

    scene = rungs.scene_of(
        35, 25, size=SIZE, crop=CropSpec(x=(3.0, 19.0)),
        cut_planes=(CutPlane(normal=(0.0, 1.0, 0.3), offset=2.0, thickness=30.0),),
        cursor=CursorSpec(position=(20.0, 9.0, 14.0), width=3, length=16.0),
    )  # fmt: skip
    bricked = render(scene, fidelity="cycle", arch=_machine(), volume=head)
    one = render(scene, fidelity="cycle", arch=_machine(limit=SIZE), volume=head)
    fixed = render(scene, fidelity="functional", arch=_machine(), volume=head)
    assert np.array_equal(bricked.image, fixed.image)
    assert psnr(bricked.image, one.image) > 50.0
