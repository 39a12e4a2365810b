"""Extremes of the fixed-point datapath, rendered whole: each case states what must hold.

Unit-level extremes (alpha 0/1, zero gradients, light parallel/antiparallel, exponents,
accumulation underflow, address ranges) live with each unit in tests/units.
"""

from __future__ import annotations

import numpy as np
import pytest
from numeric_bound import agreement, machine_pair

from hwsim.golden import make_plan, render_golden
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import Light, RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import TransferFunction, resolve_transfer
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume
from models.frame import frame_of
from models.functional import render_functional

pytestmark = [pytest.mark.model, pytest.mark.extremes]


def functional(scene, volume, arch="volumepro500", tf=None):
    machine = resolve_arch(arch)
    tf = tf or resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    return (
        render_functional(frame_of(scene, volume, tf, machine, plan)),
        render_golden(scene, volume, tf, sampling=machine.order, leap=False),
    )


def assert_within_bound(scene, volume, arch="volumepro500", tf=None):
    """Golden (with the machine's algorithms) and functional within the per-pixel bound
    derived from the formats (``numeric_bound``, docs/numerics.md); returns the
    functional result."""
    golden, fixed, bound = machine_pair(scene, volume, arch, tf)
    assert np.isfinite(fixed.image).all()
    assert fixed.samples == golden.samples
    result = agreement(golden.image, fixed.image, bound)
    assert result.ok, str(result)
    return fixed


@pytest.mark.parametrize(("dtype", "bits"), [(np.uint8, 8), (np.uint16, 12), (np.uint16, 16)])
def test_voxel_zero_and_full_scale_survive_the_datapath_exactly(dtype, bits):
    full = (1 << bits) - 1
    data = np.zeros((6, 6, 6), dtype=dtype)
    data[2:4, 2:4, 2:4] = full
    volume = Volume(data=data, bits=bits)
    scene = Scene(
        view=ViewSpec(azimuth=0, elevation=0, width=8, height=8, zoom=1.7),
        render=RenderSpec(mode="mip", sample_spacing=0.5),
    )
    fixed, golden = functional(scene, volume, "cube4")
    # Voxel centres are sampled exactly; MIP returns the exact extremes in volume units.
    assert fixed.image.max() == full and fixed.image.min() == 0
    np.testing.assert_array_equal(fixed.image, golden.image)


@pytest.mark.parametrize("shape", [(1, 1, 1), (1, 5, 7), (7, 1, 5), (13, 11, 9)])
def test_tiny_and_non_power_of_two_volumes_render_like_golden(shape):
    # Smooth data: a tilted ramp plus a bump, full 12-bit range.  (White noise with
    # full-scale jumps between neighbours is bounded by interp.error_bound instead.)
    z, y, x = np.meshgrid(*[np.linspace(0, 1, n) for n in shape], indexing="ij")
    smooth = 0.4 * (x + y + z) / 3 + 0.6 * np.exp(-((x - 0.5) ** 2 + (y - 0.4) ** 2) * 4)
    volume = Volume(data=np.round(smooth * 4095).astype(np.uint16), bits=12)
    scene = Scene(
        transfer=TransferSpec(preset="ramp"),
        view=ViewSpec(azimuth=30, elevation=20, width=16, height=16),
    )
    assert_within_bound(scene, volume)


@pytest.mark.parametrize(
    ("az", "el"), [(0, 0), (90, 0), (0, 90), (0, -90), (45, 0), (180, 0), (45, 35.26439)]
)
def test_axis_diagonal_and_reversed_views(az, el):
    volume = make_phantom("head", size=48)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=48, height=48, zoom=1.3),
    )
    assert_within_bound(scene, volume)


def test_constant_volume_has_zero_gradient_and_shades_ambient_only():
    volume = Volume(data=np.full((8, 8, 8), 1000, dtype=np.uint16), bits=12)
    tf = TransferFunction(
        values=np.array([0.0, 4095.0]), rgba=np.array([[0.8, 0.4, 0.2, 0.3], [0.8, 0.4, 0.2, 0.3]])
    )
    scene = Scene(
        view=ViewSpec(azimuth=30, elevation=20, width=12, height=12, zoom=1.5),
        lights=(Light(direction=(0, 0, 1)),),
    )
    fixed = assert_within_bound(scene, volume, tf=tf)
    hit = fixed.image[..., 3] > 0.5
    colour = fixed.image[hit][:, :3] / fixed.image[hit][:, 3:]
    # ka * c = 0.15 * (0.8, 0.4, 0.2); 8-bit output and the division add < 2/255.
    np.testing.assert_allclose(
        colour, np.broadcast_to([0.12, 0.06, 0.03], colour.shape), atol=2 / 255
    )


@pytest.mark.parametrize("supersampling", [0.5, 8.0])
def test_supersampling_extremes_keep_the_image(supersampling):
    volume = make_phantom("head", size=40)
    base = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=20, width=40, height=40, zoom=1.3),
    )
    scene = base.replace(render=RenderSpec(supersampling=supersampling))
    fixed = assert_within_bound(scene, volume, "volumepro1000")
    # Opacity correction keeps the total opacity (measured within 1.2%); detail differs
    # because half-rate sampling skips thin bone (algorithmic, not numerical).
    plain, _ = functional(base, volume, "volumepro1000")
    ratio = fixed.image[..., 3].mean() / plain.image[..., 3].mean()
    assert abs(ratio - 1) < 0.03


def test_a_thousand_low_alpha_samples_accumulate_without_stalling_early():
    """1024 samples of alpha 1/512 each: 1 - (1 - 1/512)^1024 = 0.865 in exact arithmetic."""
    n = 1024
    volume = Volume(data=np.full((n, 3, 3), 100, dtype=np.uint16), bits=12)
    tf = TransferFunction(
        values=np.array([0.0, 4095.0]), rgba=np.array([[1, 1, 1, 1 / 512], [1, 1, 1, 1 / 512]])
    )
    scene = Scene(
        view=ViewSpec(azimuth=0, elevation=0, width=1, height=1, zoom=1.0),
        render=RenderSpec(lighting=False),
    )
    fixed, golden = functional(scene, volume, "cube4", tf)
    expected = 1 - (1 - 1 / 512) ** n
    assert golden.image[0, 0, 3] == pytest.approx(expected, rel=1e-9)
    # 1/512 is 8 LSB of a UQ1.12 alpha; UQ1.16 accumulation loses < 1 LSB per step.
    assert abs(fixed.image[0, 0, 3] - expected) <= 2 / 255
