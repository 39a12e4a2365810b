"""Golden renderer against closed forms: chord lengths, Gaussian line integrals, slabs, MIP."""

from __future__ import annotations

import numpy as np
import pytest
from golden_helpers import flat_tf, gaussian_volume, make_scene

from hwsim.golden import Camera, render_golden
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume

pytestmark = pytest.mark.golden


def distance_from_axis(scene, volume) -> np.ndarray:
    """World distance of each pixel's ray from the volume centre (parallel views)."""
    cam = Camera.from_view(scene.view, volume)
    return np.linalg.norm(cam.origins, axis=1).reshape(scene.view.height, scene.view.width)


@pytest.mark.parametrize(("az", "el"), [(0, 0), (90, 0), (0, 90), (30, 20), (45, 45)])
def test_xray_of_a_uniform_ball_is_value_times_chord_length(az, el):
    value, n, radius = 100.0, 48, 0.8
    ball = make_phantom("ball", size=n, radius=radius, value=value)
    scene = make_scene("xray", az, el, size=64, sample_spacing=0.5)
    image = render_golden(scene, ball, flat_tf(1, 0)).image
    r = radius * n / 2  # phantom radius in voxels (spacing 1)
    d = distance_from_axis(scene, ball)
    chord = 2 * np.sqrt(np.clip(r**2 - d**2, 0, None)) * value
    # The sample lattice puts each end of a chord within dt of the true crossing and the
    # partial-volume edge is blurred by half a voxel: |error| <= value * (dt + 0.5).
    inner = d < 0.9 * r
    assert np.abs(image - chord)[inner].max() <= value * (0.5 + 0.5)
    # Away from the edge only the lattice end effect remains: under 1% of the chord.
    core = d < 0.5 * r
    assert (np.abs(image - chord)[core] / chord[core]).max() < 0.01
    # Partial-volume voxels have centres within r + sqrt(3)/2 and trilinear support adds
    # sqrt(3): a ray passing farther than r + 2.6 from the centre meets only zeros.
    assert np.all(image[d > r + 2.6] == 0)


def test_xray_of_a_gaussian_blob_matches_its_line_integral_with_anisotropic_spacing():
    sigma, peak = 5.0, 1000.0
    # Twice as many z voxels at half the spacing: a sphere in world units.
    volume = gaussian_volume((64, 32, 32), sigma=sigma, spacing=(0.5, 1.0, 1.0), peak=peak)
    for az, el in ((0, 0), (90, 0), (35, 25)):
        scene = make_scene("xray", az, el, size=48, sample_spacing=0.25)
        image = render_golden(scene, volume, flat_tf(1, 0)).image
        b = distance_from_axis(scene, volume)
        expected = peak * sigma * np.sqrt(2 * np.pi) * np.exp(-(b**2) / (2 * sigma**2))
        strong = expected > 0.1 * expected.max()
        # Trilinear error is at most h^2/8 |f''| per axis; for a Gaussian |f''/f| =
        # |b^2/sigma^2 - 1| / sigma^2 <= 0.15 where f > 0.1 peak (b <= 2.15 sigma), so the
        # line integral is off by under 1.8% (h = 1); tails cut by the box are < 0.2%.
        rel = np.abs(image - expected)[strong] / expected[strong]
        assert rel.max() < 0.02, (az, el, rel.max())


def test_anisotropic_ellipsoid_that_is_a_world_sphere_projects_round():
    n, spacing, radius = (24, 48, 48), (2.0, 1.0, 1.0), 18.0
    axes = [(np.arange(k) - (k - 1) / 2) * s for k, s in zip(n, spacing, strict=True)]
    # Partial-volume voxelisation with 4 sub-samples per axis.
    sub = (np.arange(4) + 0.5) / 4 - 0.5
    z, y, x = np.meshgrid(*axes, indexing="ij")
    occ = np.zeros(n)
    for dz in sub * spacing[0]:
        for dy in sub:
            for dx in sub:
                occ += ((x + dx) ** 2 + (y + dy) ** 2 + (z + dz) ** 2) <= radius**2
    volume = Volume(data=occ / 64.0, spacing=spacing)
    scene = make_scene("xray", 90, 0, size=48, sample_spacing=0.5)  # looks along +x
    image = render_golden(scene, volume, flat_tf(1, 0)).image
    d = distance_from_axis(scene, volume)
    chord = 2 * np.sqrt(np.clip(radius**2 - d**2, 0, None))
    core = d < 0.5 * radius
    assert (np.abs(image - chord)[core] / chord[core]).max() < 0.02
    # Round: the footprint's extent is the same along image rows and columns.
    mask = image > 0.5 * image.max()
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    assert abs((rows[-1] - rows[0]) - (cols[-1] - cols[0])) <= 1


@pytest.mark.parametrize("n", [5, 8, 13])
def test_uniform_slab_composites_to_one_minus_one_minus_alpha_to_the_n(n):
    alpha = 0.1
    volume = Volume(data=np.full((n, 9, 9), 50.0))
    scene = make_scene("composite", 0, 0, size=4, zoom=4.0, lighting=False)
    result = render_golden(scene, volume, flat_tf(100, alpha))
    # Rays along z through the central pixels cross n voxel lengths: n samples at dt = 1.
    centre = result.image[1:3, 1:3]
    np.testing.assert_allclose(centre[..., 3], 1 - (1 - alpha) ** n, rtol=1e-12)
    np.testing.assert_allclose(centre[..., :3] / centre[..., 3:], [[[1, 0.5, 0.25]] * 2] * 2)


def test_opacity_correction_keeps_the_image_when_sample_spacing_halves():
    volume = gaussian_volume(40, sigma=7.0)
    tf = flat_tf(1000, 0.0)
    tf = type(tf)(values=np.array([0, 1000.0]), rgba=np.array([[1, 0.6, 0.3, 0], [1, 1, 1, 0.4]]))
    images = [
        render_golden(make_scene("composite", 30, 20, size=48, sample_spacing=s), volume, tf).image
        for s in (1.0, 0.5, 0.25)
    ]
    coarse, mid, fine = (np.abs(images[i] - images[2]).max() for i in (0, 1, 2))
    # Without correction, halving the spacing doubles the optical depth (alpha 0.4 ->
    # visibly denser). With it, only the O(dt) quadrature error of a smooth integrand is
    # left, and it shrinks as dt does.
    assert coarse < 0.01 and mid < coarse / 1.5 and fine == 0
    uncorrected = 1 - (1 - 0.4) ** 2
    assert uncorrected - 0.4 > 10 * coarse


@pytest.mark.parametrize("nz", [7, 8])
def test_axis_aligned_mip_equals_the_maximum_along_the_axis(nz, rng):
    n = 16
    data = rng.uniform(0, 1000, size=(nz, n, n))
    volume = Volume(data=data)
    radius = 0.5 * np.linalg.norm(volume.extent)
    # One pixel per voxel: pixel size 2R / (zoom * n) = 1.
    scene = make_scene("mip", 0, 0, size=n, zoom=2 * radius / n, sample_spacing=0.5)
    image = render_golden(scene, volume, flat_tf(1, 0)).image
    # Looking along +z, image rows run down y and columns run along -x.
    np.testing.assert_allclose(image, data.max(axis=0)[::-1, ::-1], rtol=0, atol=1e-9)
    minip = render_golden(
        make_scene("minip", 0, 0, size=n, zoom=2 * radius / n, sample_spacing=0.5),
        volume,
        flat_tf(1, 0),
    ).image
    np.testing.assert_allclose(minip, data.min(axis=0)[::-1, ::-1], rtol=0, atol=1e-9)
