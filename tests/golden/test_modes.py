"""Golden renderer behaviour: symmetry, sizes, modes, masks, cameras, architecture plans."""

from __future__ import annotations

import numpy as np
import pytest
from golden_helpers import flat_tf, gaussian_volume, make_scene

from hwsim.core.errors import InputError
from hwsim.golden import make_plan, render_golden
from hwsim.spec.scene import CropSpec, CutPlane, Light
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume

pytestmark = pytest.mark.golden

TF = TransferFunction(
    values=np.array([0, 1000.0]), rgba=np.array([[1, 0.6, 0.3, 0], [1, 1, 1, 0.5]])
)


def psnr(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> float:
    return float(10 * np.log10(peak**2 / np.mean((a - b) ** 2)))


@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 0), (70, 0)])
def test_xray_from_the_opposite_side_is_the_mirror_image(az, el, rng):
    volume = Volume(data=rng.uniform(0, 1, size=(11, 12, 13)))
    front = render_golden(make_scene("xray", az, el, size=20), volume, TF).image
    back = render_golden(make_scene("xray", az + 180, el, size=20), volume, TF).image
    np.testing.assert_allclose(back, front[:, ::-1], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("n", [9, 10])
def test_odd_and_even_sizes_give_centred_symmetric_images(n):
    blob = gaussian_volume(n, sigma=2.0)  # exactly symmetric under flips and axis swaps
    image = render_golden(make_scene("xray", 0, 0, size=n), blob, TF).image
    np.testing.assert_allclose(image, image[::-1, ::-1], atol=1e-9)
    np.testing.assert_allclose(image, image.T, atol=1e-9)


def test_one_voxel_volume_is_a_unit_cube():
    volume = Volume(data=np.full((1, 1, 1), 7.0))
    image = render_golden(make_scene("xray", 0, 0, size=1, zoom=1.7), volume, TF).image
    assert image.shape == (1, 1) and image[0, 0] == pytest.approx(7.0)  # 7 x 1 voxel
    for mode in ("composite", "mip", "minip", "iso"):
        out = render_golden(make_scene(mode, 30, 20, size=3), volume, flat_tf(10, 0.5)).image
        assert np.isfinite(out).all()


def test_constant_volume_shades_ambient_only_without_nan():
    volume = Volume(data=np.full((6, 6, 6), 50.0))
    tf = flat_tf(100, 0.3, rgb=(0.8, 0.4, 0.2))
    scene = make_scene("composite", 30, 20, size=8, zoom=2.0)
    image = render_golden(scene, volume, tf).image
    assert np.isfinite(image).all()
    hit = image[..., 3] > 0
    colour = image[hit][:, :3] / image[hit][:, 3:]
    np.testing.assert_allclose(colour, np.broadcast_to([0.12, 0.06, 0.03], colour.shape))


@pytest.mark.parametrize("mode", ["composite", "mip", "minip", "xray", "iso"])
@pytest.mark.parametrize("projection", ["parallel", "perspective"])
def test_every_mode_renders_finite_images_of_the_documented_shape(mode, projection):
    volume = gaussian_volume(24)
    scene = make_scene(mode, 20, 10, size=16, height=12, projection=projection, iso_value=500.0)
    result = render_golden(scene, volume, TF)
    expected = (12, 16, 4) if mode in ("composite", "iso") else (12, 16)
    assert result.image.shape == expected and result.image.dtype == np.float64
    assert np.isfinite(result.image).all() and result.samples > 0
    if mode == "mip":
        assert result.image.max() <= 1000 and result.image.min() >= volume.value_range[0]
    if mode == "iso":
        assert set(np.unique(result.image[..., 3])) == {0.0, 1.0}


def test_perspective_enlarges_an_object_as_the_eye_approaches():
    ball = make_phantom("ball", size=24, radius=0.5)
    far = render_golden(make_scene("xray", 0, 0, size=40, projection="perspective"), ball, TF)
    scene = make_scene("xray", 0, 0, size=40, projection="perspective")
    near_view = scene.view.__class__(**{**scene.view.__dict__, "distance": 1.5})
    near = render_golden(scene.replace(view=near_view), ball, TF)
    assert (near.image > 0).sum() > 1.5 * (far.image > 0).sum()
    np.testing.assert_allclose(far.image, far.image[::-1, ::-1], atol=1e-6)  # centred


def test_crop_box_removes_what_lies_outside():
    volume = Volume(data=np.ones((10, 10, 10)))
    scene = make_scene("xray", 0, 0, size=10, zoom=2 * 0.5 * np.sqrt(300) / 10)
    full = render_golden(scene, volume, TF).image
    half = render_golden(scene.replace(crop=CropSpec(z=(0, 4.5))), volume, TF).image
    np.testing.assert_allclose(half, full / 2)
    outside = render_golden(scene.replace(crop=CropSpec(z=(0, 4.5), invert=True)), volume, TF)
    np.testing.assert_allclose(outside.image + half, full)


def test_cut_plane_keeps_a_slab_with_linear_falloff():
    volume = Volume(data=np.ones((20, 4, 4)))
    scene = make_scene("xray", 0, 0, size=1, zoom=3.0, sample_spacing=0.125)
    plane = CutPlane(normal=(0, 0, 1), offset=0.0, thickness=4.0, falloff=2.0)
    image = render_golden(scene.replace(cut_planes=(plane,)), volume, TF).image
    # Slab of 4 plus two linear ramps of width 2 (each worth 1): about 6 world units.
    assert image[0, 0] == pytest.approx(6.0, abs=0.15)


def test_early_termination_stops_rays_without_changing_them_much():
    volume = gaussian_volume(32, sigma=8.0)
    scene = make_scene("composite", 30, 20, size=24)
    full = render_golden(scene, volume, TF)
    cut = render_golden(
        scene.replace(render=scene.render.__class__(early_termination=0.95)), volume, TF
    )
    assert cut.samples < full.samples
    # A stopped ray misses at most 1 - 0.95 of its opacity and premultiplied colour.
    assert np.abs(cut.image - full.image).max() <= 0.05 + 1e-12


@pytest.mark.parametrize("sampling", ["shear-warp", "shear-image", "slice-parallel"])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20), (45, 0), (10, 80), (180, 0)])
def test_architecture_sample_positions_agree_with_the_ideal_caster(sampling, az, el):
    volume = gaussian_volume(40, sigma=8.0)
    scene = make_scene("composite", az, el, size=48, lighting=False)
    ideal = render_golden(scene, volume, TF).image
    arch = render_golden(scene, volume, TF, sampling=sampling).image
    # Smooth data, same rays or a bilinear warp of the base plane: the difference is the
    # sampling pattern only (and the warp's bilinear blur), under 1% RMS.
    assert psnr(ideal, arch) > 40


def test_shear_warp_base_plane_is_sheared_and_refuses_perspective():
    volume = gaussian_volume(20)
    plan = make_plan(make_scene("composite", 45, 0, size=16), volume, "shear-warp")
    assert plan.principal_axis in (0, 2) and plan.shape[0] * plan.shape[1] > 20 * 20
    offsets = [step.zyx[0, plan.principal_axis] for step in plan.steps()]
    assert offsets == sorted(offsets) or offsets == sorted(offsets, reverse=True)
    with pytest.raises(InputError, match="parallel"):
        make_plan(
            make_scene("composite", 0, 0, size=8, projection="perspective"), volume, "shear-warp"
        )


def test_plans_are_deterministic():
    volume = gaussian_volume(16)
    scene = make_scene("composite", 33, 12, size=10, projection="perspective")
    a = [s.zyx for s in make_plan(scene, volume, "ray").steps()]
    b = [s.zyx for s in make_plan(scene, volume, "ray").steps()]
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_lights_change_shading_as_phong_predicts():
    volume = gaussian_volume(24)
    scene = make_scene("iso", 0, 0, size=24, iso_value=500.0)
    headlight = render_golden(scene.replace(lights=(Light(direction=(0, 0, 1)),)), volume, TF).image
    behind = render_golden(scene.replace(lights=(Light(direction=(0, 0, -1)),)), volume, TF).image
    centre = (12, 12)
    # Facing the headlight: ambient + diffuse + specular; lit from behind: ambient only.
    m = scene.material
    np.testing.assert_allclose(behind[centre][:3], np.multiply(m.ambient, (0.9, 0.85, 0.75)))
    assert headlight[centre][0] > 0.9 * (m.ambient + m.diffuse) * 0.9
