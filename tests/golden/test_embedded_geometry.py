"""Embedded opaque geometry: rasterisation, occlusion, depth-test variants, golden vs
functional on volumepro1000, refusal on machines without the depth buffer."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.golden import render_golden
from hwsim.golden.camera import Camera
from hwsim.golden.geometry import depth_range, rasterise, sample_depth
from hwsim.numerics import psnr
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.spec.scene_features import Box, GeometrySpec, Sphere
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.datapath import Datapath
from models.frame import frame_of

pytestmark = [pytest.mark.golden, pytest.mark.model]

ARCH = "volumepro1000"
SIZE = 40
# Opaque bone: rays that reach it end at A = 1 exactly, in float and in fixed point.
OPAQUE = (
    (-1024, 0, 0, 0, 0),
    (200, 0.9, 0.6, 0.5, 0.0),
    (300, 1.0, 1.0, 0.9, 1.0),
    (3072, 1, 1, 1, 1),
)


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=SIZE)


def scene(geometry: GeometrySpec | None, az=0.0, el=0.0, **view) -> Scene:
    return Scene(
        volume=VolumeSpec(phantom="head", params=(("size", SIZE),)),
        transfer=TransferSpec(preset=None, points=OPAQUE),
        view=ViewSpec(azimuth=az, elevation=el, width=48, height=48, zoom=1.0, **view),
        render=RenderSpec(lighting=False),
        geometry=geometry,
    )


def both(sc: Scene, volume):
    """Golden at the machine's positions without leaping (so sample counts compare) and
    the functional rung."""
    tf = resolve_transfer(sc.transfer, volume)
    g = render_golden(sc, volume, tf, sampling="shear-image", leap=False)
    f = render(sc, fidelity="functional", arch=ARCH, volume=volume)
    return g, f


# ----------------------------------------------------------------- rasterisation


def test_sphere_depth_and_colour_match_the_analytic_intersection(head):
    sphere = Sphere(center=(5.0, -3.0, 0.0), radius=10.0, color=(0.1, 0.2, 0.3))
    sc = scene(GeometrySpec(spheres=(sphere,)))
    cam = Camera.from_view(sc.view, head)
    buf = rasterise(sc.geometry, cam, sc.view.distance)
    near, far = depth_range(cam, sc.view.distance)
    o = cam.origins
    # View along +z: a pixel at (x, y) hits z = -sqrt(r^2 - dx^2 - dy^2); t = z.
    r2 = (o[:, 0] - 5.0) ** 2 + (o[:, 1] + 3.0) ** 2
    hit = r2 <= 100.0
    assert hit.sum() > 20 and (~hit).sum() > 20
    t = -np.sqrt(100.0 - r2[hit])
    assert np.allclose(buf.depth[hit], (t - near) / (far - near), atol=1e-12)
    assert np.all(buf.depth[~hit] == 1.0) and np.all(buf.rgba[~hit] == 0.0)
    assert np.allclose(buf.rgba[hit], [0.1, 0.2, 0.3, 1.0])


def test_box_front_face_and_nearest_primitive_wins(head):
    box = Box(lo=(-8.0, -8.0, -4.0), hi=(8.0, 8.0, 4.0), color=(1.0, 0.0, 0.0))
    ball = Sphere(center=(0.0, 0.0, -10.0), radius=3.0, color=(0.0, 1.0, 0.0))
    sc = scene(GeometrySpec(boxes=(box,), spheres=(ball,)))
    cam = Camera.from_view(sc.view, head)
    buf = rasterise(sc.geometry, cam, sc.view.distance)
    near, far = depth_range(cam, sc.view.distance)
    x, y = cam.origins[:, 0], cam.origins[:, 1]
    in_box = (np.abs(x) < 8) & (np.abs(y) < 8)
    in_ball = x**2 + y**2 < 9
    face = in_box & ~in_ball
    assert np.allclose(buf.depth[face], (-4.0 - near) / (far - near))
    assert np.all(buf.rgba[in_ball, 1] == 1.0)  # the nearer sphere in front of the box


def test_sample_depth_is_the_normalised_ray_parameter(head):
    cam = Camera.from_view(scene(None).view, head)
    centre = np.array([[(SIZE - 1) / 2.0] * 3])
    assert sample_depth(centre, cam, head, 3.0).tolist() == [0.5]
    persp = Camera.from_view(ViewSpec(projection="perspective", distance=4.0), head)
    assert np.allclose(sample_depth(centre, persp, head, 4.0), 0.5)


# ----------------------------------------------------------------- occlusion


def test_sphere_in_front_hides_the_volume_with_its_exact_colour(head):
    colour = (0.2, 0.45, 0.95)
    wall = Sphere(center=(0.0, 0.0, -60.0), radius=50.0, color=colour)  # covers the centre
    g, f = both(scene(GeometrySpec(spheres=(wall,))), head)
    g0, f0 = both(scene(None), head)
    cam = Camera.from_view(scene(None).view, head)
    on_sphere = rasterise(GeometrySpec(spheres=(wall,)), cam, 3.0).rgba[:, 3].reshape(48, 48)
    covered = (on_sphere == 1.0) & (g0.image[..., 3] > 0.5)  # volume there without it
    assert covered.sum() > 200
    assert np.array_equal(g.image[covered], np.broadcast_to([*colour, 1.0], (covered.sum(), 4)))
    # Functional: the colour exactly as the output pixel format holds it.
    top = (1 << Datapath.for_volume(resolve_arch(ARCH), head).composite.output_bits) - 1
    want = np.floor(np.array([*colour, 1.0]) * top + 0.5) / top
    assert np.array_equal(f.image[covered], np.broadcast_to(want, (covered.sum(), 4)))
    assert g.samples < g0.samples and f.samples == g.samples


def test_sphere_behind_changes_nothing_where_the_volume_is_opaque(head):
    # Front surface at z = 25, behind the volume's box (|z| <= 20): no sample is dropped.
    back = Sphere(center=(0.0, 0.0, 70.0), radius=45.0, color=(0.0, 1.0, 0.0))
    g, f = both(scene(GeometrySpec(spheres=(back,))), head)
    g0, f0 = both(scene(None), head)
    for with_geo, without in ((g, g0), (f, f0)):
        opaque = without.image[..., 3] == 1.0
        assert opaque.sum() > 100
        assert np.array_equal(with_geo.image[opaque], without.image[opaque])
        # Where the volume is not opaque the sphere shows through: the test can fail.
        seen = (~opaque) & (with_geo.image[..., 1] > without.image[..., 1] + 0.1)
        assert seen.sum() > 50
    assert f.samples == f0.samples


@pytest.mark.parametrize(("first", "second"), [("<", ">="), ("<=", ">"), ("==", "!=")])
def test_complementary_depth_tests_partition_the_samples(head, first, second):
    slab = Box(lo=(-40.0, -40.0, -2.0), hi=(40.0, 40.0, 2.0), color=(1.0, 1.0, 0.0))
    runs = {}
    for test in (first, second):
        runs[test] = both(scene(GeometrySpec(depth_test=test, boxes=(slab,)), az=20), head)
    none = both(scene(None, az=20), head)
    for k in (0, 1):  # golden, functional
        assert runs[first][k].samples + runs[second][k].samples == none[k].samples
    assert runs[first][1].samples == runs[first][0].samples or first == "=="


def test_less_equal_keeps_at_least_what_less_keeps_and_equal_hits_samples_on_the_face(head):
    # A face exactly on a slice plane (z index 19.0 -> world -0.5): samples there tie.
    slab = Box(lo=(-40.0, -40.0, -0.5), hi=(40.0, 40.0, 40.0), color=(1.0, 1.0, 0.0))
    counts = {}
    for test in ("<", "<=", "=="):
        sc = scene(GeometrySpec(depth_test=test, boxes=(slab,)))
        counts[test] = render(sc, fidelity="functional", arch=ARCH, volume=head).samples
    assert counts["=="] > 0
    assert counts["<="] == counts["<"] + counts["=="]


# ----------------------------------------------------------------- golden vs functional


@pytest.mark.parametrize("projection", ["parallel", "perspective"])
def test_functional_is_within_40_db_of_golden_with_geometry(projection):
    volume = make_phantom("head", size=64)
    geometry = GeometrySpec(
        spheres=(Sphere(center=(15.0, 10.0, 0.0), radius=12.0, color=(0.2, 0.45, 0.95)),),
        boxes=(Box(lo=(-60.0, -3.0, -3.0), hi=(5.0, 3.0, 3.0), color=(0.95, 0.3, 0.2)),),
    )
    sc = Scene(
        volume=VolumeSpec(phantom="head", params=(("size", 64),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(
            azimuth=30, elevation=15, width=64, height=64, zoom=1.3, projection=projection
        ),
        geometry=geometry,
    )
    g, f = both(sc, volume)
    assert f.samples == g.samples
    assert psnr(g.image, f.image) >= 40.0
    # The geometry is in the picture: differs from the render without it.
    g0 = render(dataclasses.replace(sc, geometry=None), fidelity="golden", arch=ARCH, volume=volume)
    assert np.abs(g.image - g0.image).max() > 0.5


# ----------------------------------------------------------------- refusal


def test_machines_without_the_depth_buffer_refuse_geometry(head):
    sc = scene(GeometrySpec(spheres=(Sphere(center=(0, 0, 0), radius=5.0),)))
    with pytest.raises(InputError, match="features.embedded_geometry") as err:
        render(sc, fidelity="functional", arch="cube4", volume=head)
    assert "volumepro1000" in str(err.value) and "\n" not in str(err.value)


def test_geometry_needs_composite_mode_and_image_rays(head):
    sc = scene(GeometrySpec(spheres=(Sphere(center=(0, 0, 0), radius=5.0),)))
    mip = sc.replace(render=RenderSpec(mode="mip"))
    with pytest.raises(InputError, match="render.mode"):
        render(mip, fidelity="functional", arch=ARCH, volume=head)
    with pytest.raises(InputError, match="geometry"):
        render(sc, fidelity="golden", sampling="shear-warp", volume=head)


@pytest.mark.parametrize(("test", "stops"), [("<", True), ("<=", True), (">=", False)])
def test_rays_end_at_the_geometry_for_front_to_back_tests(head, test, stops):
    """``<`` / ``<=``: once a sample fails, every later one does (depth grows along the
    ray), so the back end ends the ray there (as early termination does); other tests
    leave rays running."""
    from hwsim.golden import make_plan
    from models.backend import Backend
    from models.units import interp

    wall = Sphere(center=(0.0, 0.0, -60.0), radius=50.0, color=(1.0, 1.0, 1.0))
    sc = scene(GeometrySpec(depth_test=test, spheres=(wall,)))
    arch = resolve_arch(ARCH)
    plan = make_plan(sc, head, arch.order)
    be = Backend(frame_of(sc, head, resolve_transfer(sc.transfer, head), arch, plan))
    state = be.new_state(plan.n_rays)

    class Source:  # unlit, post-classified: only values are read
        def __init__(self, step):
            self.taps = interp.interp_taps(step.zyx, head.shape, be.dp.interp)

        def value(self):
            return interp.interpolate(be.raw.ravel(), self.taps, be.dp.interp)

    for step in plan.steps():
        be.process(step, Source, state)
    covered = be.depth.alpha > 0
    sampled = np.zeros(plan.n_rays, bool)
    sampled[plan.ray_ids] = True
    assert (covered & sampled).sum() > 100
    assert (~state.alive[covered & sampled]).all() == stops
    assert state.alive[~covered & sampled & (state.acc[:, 3] == 0)].all()
