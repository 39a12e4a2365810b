"""Sample plans and empty-space leaping: determinism, reproduction, exactness of leaping."""

from __future__ import annotations

import numpy as np
import pytest
from golden_helpers import flat_tf, gaussian_volume, make_scene
from scipy import ndimage

from hwsim.golden import make_plan, render_golden
from hwsim.golden.occupancy import block_ranges, opacity_can_be_positive
from hwsim.spec.scene import CropSpec, CutPlane, RenderSpec
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume

pytestmark = pytest.mark.golden

# Opacity only inside [300, 600]: a Gaussian blob of peak 1000 is a translucent shell,
# with empty space outside it *and* inside its core.
SHELL = TransferFunction(
    values=np.array([0.0, 300.0, 450.0, 600.0, 1000.0]),
    rgba=np.array(
        [[1, 0.5, 0.2, 0], [1, 0.5, 0.2, 0], [0.9, 0.8, 0.3, 0.3], [0.2, 0.6, 1, 0], [1, 1, 1, 0]]
    ),
)


def test_opacity_interval_test_matches_brute_force(rng):
    values, alpha = SHELL.values, SHELL.rgba[:, 3]
    lo = rng.uniform(-100, 1100, 3000)
    hi = lo + rng.exponential(100, 3000) * (rng.uniform(size=3000) > 0.2)
    got = opacity_can_be_positive(lo, hi, values, alpha)
    grid = lo[:, None] + (hi - lo)[:, None] * np.linspace(0, 1, 2001)
    want = (np.interp(grid, values, alpha) > 0).any(axis=1)
    # The grid can only miss a positive stretch narrower than its spacing: never the
    # other way round (the test is exact, the grid conservative from below).
    assert np.all(got >= want) and (got != want).mean() < 0.01


def test_block_ranges_cover_every_trilinear_cell(rng):
    data = rng.integers(0, 1000, size=(9, 10, 11)).astype(np.int16)
    lo, hi = block_ranges(data, 4)
    for z, y, x in rng.integers(0, [8, 9, 10], size=(200, 3)):
        cell = data[z : z + 2, y : y + 2, x : x + 2]
        b = (z // 4, y // 4, x // 4)
        assert lo[b] <= cell.min() and cell.max() <= hi[b]


SCENES = {
    "post-lit": {},
    "unlit": {"lighting": False},
    "supersampled": {"sample_spacing": 0.5, "supersampling": 2.0},
    "nearest": {"interpolation": "nearest"},
    "sample-gradient": {"gradient": "sample"},
    "ert": {"early_termination": 0.9},
}


@pytest.mark.parametrize("sampling", ["ray", "shear-image"])
def test_leaping_is_exact_in_perspective_where_every_ray_has_its_own_step(sampling):
    # Regression: the backward pass once used the per-ray steps read before the forward
    # pass had dropped rays with no occupied block, so later rays leapt by another ray's
    # step and skipped visible samples (max difference ~0.008 on this scene).
    from hwsim.spec.scene import TransferSpec
    from hwsim.spec.transfer import resolve_transfer

    volume = make_phantom("head", size=21)
    tf = resolve_transfer(TransferSpec(preset="ct"), volume, None)
    scene = make_scene("composite", 30, 20, size=28, zoom=1.2, projection="perspective")
    full = render_golden(scene, volume, tf, sampling=sampling, leap=False)
    fast = render_golden(scene, volume, tf, sampling=sampling)
    np.testing.assert_array_equal(fast.image, full.image)
    assert fast.samples < full.samples


@pytest.mark.parametrize("sampling", ["ray", "shear-warp", "shear-image"])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_leaping_never_changes_the_image(name, sampling):
    volume = gaussian_volume(36, sigma=6.0)
    scene = make_scene("composite", 30, 20, size=40, **SCENES[name])
    full = render_golden(scene, volume, SHELL, sampling=sampling, leap=False)
    fast = render_golden(scene, volume, SHELL, sampling=sampling)
    np.testing.assert_array_equal(fast.image, full.image)
    assert fast.samples < 0.7 * full.samples  # the corners and the core are skipped


@pytest.mark.parametrize(
    "change",
    [
        {"order": "pre"},
        {"gradient_points": np.array([[0.0, 0.0], [40.0, 1.0]])},
        {"crop": CropSpec(x=(5, 25))},
        {"cut": CutPlane(normal=(1, 1, 0), offset=2.0, thickness=4.0, falloff=3.0)},
        {"projection": "perspective"},
        {"iso": 500.0},
        {"iso": 2000.0},  # nothing reaches it: every ray is empty
    ],
    ids=["pre", "modulated", "crop", "cut", "perspective", "iso", "iso-none"],
)
def test_leaping_is_exact_with_every_feature(change):
    volume = gaussian_volume((30, 34, 38), sigma=6.0, spacing=(1.2, 1.0, 0.9))
    tf = SHELL
    if "order" in change or "gradient_points" in change:
        tf = TransferFunction(values=SHELL.values, rgba=SHELL.rgba, **change)
    mode = "iso" if "iso" in change else "composite"
    scene = make_scene(mode, -40, 25, size=32, projection=change.get("projection", "parallel"))
    if "iso" in change:
        scene = scene.replace(render=RenderSpec(mode="iso", iso_value=change["iso"]))
    if "crop" in change:
        scene = scene.replace(crop=change["crop"])
    if "cut" in change:
        scene = scene.replace(cut_planes=(change["cut"],))
    full = render_golden(scene, volume, tf, leap=False)
    fast = render_golden(scene, volume, tf)
    np.testing.assert_array_equal(fast.image, full.image)
    assert fast.samples <= full.samples


def test_a_fully_transparent_volume_takes_no_samples():
    volume = gaussian_volume(16)
    result = render_golden(make_scene("composite", 10, 10, size=8), volume, flat_tf(1000, 0.0))
    assert result.samples == 0 and not result.image.any()


def test_the_plan_positions_reproduce_the_image_with_an_independent_sampler():
    """Re-render from the plan's own positions with scipy and a plain loop per step."""
    volume = make_phantom("ball", size=20, radius=0.7, value=100.0)
    scene = make_scene("composite", 25, 35, size=24, lighting=False, early_termination=0.8)
    tf = flat_tf(200, 0.15, rgb=(0.2, 0.7, 0.9))
    result = render_golden(scene, volume, tf)
    acc = np.zeros((result.plan.n_rays, 4))
    for step in result.plan.steps():
        alive = acc[step.rays, 3] < 0.8
        rays, zyx = step.rays[alive], step.zyx[alive]
        v = ndimage.map_coordinates(volume.data.astype(float), zyx.T, order=1, mode="nearest")
        rgba = tf.classify(v)
        a = 1 - (1 - rgba[:, 3]) ** (step.dt / 1.0)
        w = (1 - acc[rays, 3]) * a
        acc[rays, :3] += w[:, None] * rgba[:, :3]
        acc[rays, 3] += w
    np.testing.assert_allclose(result.plan.to_image(acc), result.image, rtol=0, atol=1e-12)


def test_plans_are_deterministic_and_describe_themselves():
    volume = gaussian_volume(16)
    scene = make_scene("composite", 33, 12, size=10, projection="perspective")
    plans = [make_plan(scene, volume, "ray") for _ in range(2)]
    a, b = ([(s.rays, s.zyx, s.dt, s.view) for s in p.steps()] for p in plans)
    assert len(a) == len(b) == plans[0].n_steps
    for x, y in zip(a, b, strict=True):
        for u, v in zip(x, y, strict=True):
            np.testing.assert_array_equal(u, v)
    views = np.concatenate([s.view for s in plans[0].steps()])
    np.testing.assert_allclose(np.linalg.norm(views, axis=1), 1.0)
    info = plans[0].describe()
    assert info["samples"] == plans[0].samples == sum(s.rays.size for s in plans[0].steps())
    assert info["kind"] == "ray" and info["leap_block"] is None


@pytest.mark.parametrize("sampling", ["shear-warp", "shear-image"])
def test_slice_plans_sample_exactly_on_slices(sampling):
    volume = Volume(data=np.zeros((9, 10, 11)), spacing=(1.0, 0.8, 1.1))
    scene = make_scene("composite", 50, 30, size=12, supersampling=2.0)
    plan = make_plan(scene, volume, sampling)
    for step in plan.steps():
        q = step.zyx[:, plan.principal_axis] * 2
        assert np.array_equal(q, np.round(q)) and np.unique(q).size <= 1


@pytest.mark.parametrize("projection", ["parallel", "perspective"])
@pytest.mark.parametrize("order", ["front-to-back", "back-to-front"])
def test_shear_image_positions_compiled_match_their_numpy_form(projection, order):
    volume = Volume(data=np.zeros((9, 10, 11)), spacing=(1.0, 0.8, 1.1))
    scene = make_scene(
        "composite", 37, 21, size=12, supersampling=3.0, projection=projection, blend_order=order
    )
    whole = make_plan(scene, volume, "shear-image")

    def steps_equal(plan):
        rays, steps = np.arange(plan.ray_ids.size), 0
        for step_j in range(plan.n_steps):
            sel = rays[(plan.j_lo <= step_j) & (plan.j_hi >= step_j)][::-1]
            compiled = plan.position(step_j, sel)
            reference = plan._shear_image_numpy(step_j, sel)
            assert compiled.tobytes() == reference.tobytes()
            steps += sel.size > 0
        return steps

    # A subset made after the whole plan's positions: its packed rays are its own.
    assert steps_equal(whole) > 10
    assert steps_equal(whole.subset(np.arange(whole.ray_ids.size) % 3 == 1)) > 10


@pytest.mark.parametrize("sampling", ["ray", "shear-warp", "shear-image"])
@pytest.mark.parametrize("projection", ["parallel", "perspective"])
def test_steps_walk_the_rays_in_joining_order(sampling, projection):
    """``run_steps`` walks a copy of the plan whose rays are in the order they join
    (``SamplePlan.reordered``): every step holds the rays, positions, lengths and views
    of the plain walk, in its order (rays by first step, then index), dead rays dropped."""
    volume = Volume(data=np.zeros((9, 10, 11)), spacing=(1.0, 0.8, 1.1))
    scene = make_scene("composite", 37, 21, size=12, supersampling=2.0, projection=projection)
    if sampling == "shear-warp" and projection == "perspective":
        sampling = "shear-image"  # shear-warp is parallel only
    plan = make_plan(scene, volume, sampling)
    alive = np.ones(plan.n_rays, dtype=bool)
    order, steps = np.argsort(plan.j_lo, kind="stable"), 0
    for j, step in enumerate(plan.steps(alive)):
        sel = order[(plan.j_lo[order] <= j) & (plan.j_hi[order] >= j)]
        sel = sel[alive[plan.ray_ids[sel]]]
        np.testing.assert_array_equal(step.rays, plan.ray_ids[sel])
        assert step.zyx.tobytes() == plan.position(j, sel).tobytes()
        dt = plan._dt[sel] if isinstance(plan._dt, np.ndarray) else plan._dt
        np.testing.assert_array_equal(step.dt, dt)
        view = plan._view[sel] if plan._view.ndim == 2 else plan._view
        np.testing.assert_array_equal(step.view, view)
        alive[step.rays[::7]] = False  # early termination: dropped from the next step on
        steps += sel.size > 1
    assert steps > 5


def test_all_alive_is_the_gathered_test(rng):
    """``steps.all_alive(alive, rays)`` is ``alive[rays].all()`` (empty: True)."""
    from hwsim.golden.steps import all_alive

    for _ in range(50):
        alive = rng.random(40) < rng.uniform(0.8, 1.0)
        rays = rng.choice(40, int(rng.integers(0, 40)), replace=False)
        assert all_alive(alive, rays) == alive[rays].all()
    assert all_alive(np.zeros(3, dtype=bool), np.zeros(0, dtype=np.int64))
