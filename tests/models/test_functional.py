"""The functional rung: fixed point at an architecture's sample positions vs float64 golden.

Design section 3: golden at the same positions isolates the numerical error.  The pass
criterion is the per-pixel bound derived from the datapath's formats
(``numeric_bound.pixel_bound``, docs/numerics.md "End to end"): golden rendered with the
machine's algorithms (gradient source, reflectance maps) may differ from the functional
image by no more than the formats allow, pixel by pixel.  PSNR is recorded beside it
(``record_property``, and in every failure message); it is not the criterion: at 40 dB it
let a 10 % error in golden's ambient term through.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numeric_bound import agreement, golden_at_machine, machine_pair

from hwsim.run.fidelity import render
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.volumes import load_volume, make_phantom, read_volume
from models.functional import pipeline_latency

pytestmark = pytest.mark.model

VIEWS = [(0, 0), (45, 0), (30, 20), (0, 90), (180, 0), (-60, -35)]


def pair(scene: Scene, volume, arch="volumepro500"):
    """``(golden, functional, bound)``: golden with the machine's algorithms at its
    positions, every position planned (``leap=False``: sample counts compare)."""
    return machine_pair(scene, volume, arch)


def assert_within_bound(golden, fixed, bound, record_property=None):
    """The derived bound holds at every pixel and channel; PSNR is recorded."""
    result = agreement(golden.image, fixed.image, bound)
    if record_property is not None:
        record_property("psnr_db", round(result.psnr, 2))
        record_property("bound_ratio", round(result.ratio, 3))
    assert result.ok, str(result)
    return result


def head_scene(az, el, size=64, **render) -> Scene:
    return Scene(
        volume=VolumeSpec(phantom="head", params=(("size", 64),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=size, height=size, zoom=1.3),
        render=RenderSpec(**render),
    )


@pytest.fixture(scope="module")
def head64():
    return make_phantom("head", size=64)


@pytest.mark.parametrize(("az", "el"), VIEWS)
def test_composite_phong_head_is_within_the_derived_bound_of_golden(
    head64, az, el, record_property
):
    golden, fixed, bound = pair(head_scene(az, el), head64)
    assert fixed.image.shape == golden.image.shape
    assert fixed.samples == golden.samples
    assert_within_bound(golden, fixed, bound, record_property)


@pytest.mark.parametrize("arch", ["volumepro500", "volumepro1000", "cube4"])
@pytest.mark.parametrize(("az", "el"), [(30, 20), (90, 0)])
def test_every_processing_order_is_within_the_derived_bound(head64, arch, az, el, record_property):
    assert_within_bound(*pair(head_scene(az, el), head64, arch), record_property)


@pytest.mark.parametrize(("name", "preset"), [("marschner-lobb", "ramp"), ("ball", "auto")])
def test_marschner_lobb_and_ball_are_within_the_derived_bound(name, preset, record_property):
    """Float phantoms: the voxels' linear map onto 12 bits adds half a raw step."""
    volume = make_phantom(name, size=40)
    scene = Scene(
        transfer=TransferSpec(preset=preset),
        view=ViewSpec(azimuth=25, elevation=15, width=64, height=64),
    )
    assert_within_bound(*pair(scene, volume), record_property)


@pytest.mark.parametrize(("az", "el"), [(180, 0), (90, 0), (30, 20)])
def test_real_ct_is_within_the_derived_bound(shared_data, az, el, record_property):
    ct = read_volume(shared_data / "ct_cranium.nrrd")
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=96, height=96, zoom=1.2),
    )
    assert_within_bound(*pair(scene, ct), record_property)


@pytest.mark.parametrize("mode", ["mip", "minip", "xray", "iso"])
@pytest.mark.parametrize("arch", ["volumepro500", "volumepro1000"])
def test_scalar_modes_are_within_the_derived_bound(head64, mode, arch):
    """MIP / MinIP: each ray's largest sample error (volume units); X-ray: the samples'
    errors and the UQ8.12 step weight's; iso: the hit's shading where the first hit is
    the same sample on both sides, else anything (a hit may move by one sample)."""
    golden, fixed, bound = pair(head_scene(30, 20, mode=mode, iso_value=300.0), head64, arch)
    result = assert_within_bound(golden, fixed, bound)
    if mode == "iso":  # most rays' first hit is certain: the bound is not 1 everywhere
        assert np.mean(bound[..., :3] >= 1.0) < 0.01, result


#: The headline frame's golden with one shading coefficient 10 % high: the derived bound
#: must see it where the 40 dB floor did not (ambient: 44.1 dB; specular: 57.9 dB).
SHADING_ERRORS = {"ambient": 1.1, "diffuse": 1.1, "specular": 1.1}


@pytest.mark.parametrize("coefficient", list(SHADING_ERRORS))
def test_the_bound_sees_a_10_percent_shading_coefficient_error(head64, coefficient):
    """Golden alone given the changed material (what a coefficient 10 % off in golden's
    ``phong`` does); the functional image and the bound keep the scene's."""
    scene = head_scene(30, 20)
    golden, fixed, bound = pair(scene, head64)
    assert agreement(golden.image, fixed.image, bound).ok  # control
    value = getattr(scene.material, coefficient) * SHADING_ERRORS[coefficient]
    wrong = scene.replace(material=dataclasses.replace(scene.material, **{coefficient: value}))
    _, mutated = golden_at_machine(wrong, head64, "volumepro500")
    result = agreement(mutated.image, fixed.image, bound)
    assert not result.ok, str(result)


@pytest.mark.xfail(
    strict=True,
    raises=AssertionError,
    reason="finding: shininess 24 -> 25 moves a pixel by at most 0.0043 over 35 frames "
    "(0.0032 here; about one 8-bit output step), only at highlights, where ks n x^(n-1) "
    "times the SQ1.10 normal's error allows 0.012-0.15 (docs/numerics.md)",
)
def test_the_bound_sees_the_shininess_one_higher(head64):
    scene = head_scene(30, 20)
    golden, fixed, bound = pair(scene, head64)
    shininess = scene.material.shininess + 1
    wrong = scene.replace(material=dataclasses.replace(scene.material, shininess=shininess))
    _, mutated = golden_at_machine(wrong, head64, "volumepro500")
    assert not agreement(mutated.image, fixed.image, bound).ok


def test_functional_is_deterministic(head64):
    scene = head_scene(30, 20)
    a = pair(scene, head64)[1]
    b = pair(scene, head64)[1]
    assert np.array_equal(a.image, b.image) and a.cycles == b.cycles


def test_cycle_estimate_of_a_dense_volume_reproduces_volumepro500_30_fps():
    """256^3 on 4 pipelines at 125 MHz: one sample per voxel, 2^24 / 4 cycles = 29.8 fps."""
    n = 256
    volume = make_phantom("ball", size=n, radius=1.0)
    scene = Scene(
        view=ViewSpec(azimuth=0, elevation=0, width=32, height=32), render=RenderSpec(mode="mip")
    )
    run = render(scene, fidelity="functional", arch="volumepro500", volume=volume)
    assert run.samples == n**3
    assert run.cycles == n**3 // 4 + pipeline_latency(scene, modulates=False)
    fps = run.clock_hz / run.cycles
    assert fps == pytest.approx(125e6 / (n**3 / 4), rel=1e-5)
    assert 29.7 < fps < 29.9


def test_functional_rung_runs_from_the_library_entry_point(tmp_path):
    scene = Scene(
        volume=VolumeSpec(phantom="ball", params=(("size", 24),)),
        view=ViewSpec(width=24, height=24),
    )
    run = render(scene, fidelity="functional")
    assert run.arch == "volumepro500" and run.cycles > 0 and run.clock_hz == 125e6
    assert run.image.shape == (24, 24, 4) and np.isfinite(run.image).all()
    assert load_volume(scene.volume).shape == (24, 24, 24)


def test_a_small_image_does_not_shorten_a_slice_order_machine_s_slices():
    """VolumePro 1000 streams every voxel of a slice however few rays the image casts."""
    from hwsim.run.fidelity import resolve_arch

    n = 24
    volume = make_phantom("ball", size=n, radius=1.0)
    scene = Scene(
        view=ViewSpec(azimuth=0, elevation=0, width=8, height=8), render=RenderSpec(mode="mip")
    )
    arch = resolve_arch("volumepro1000")
    run = render(scene, fidelity="functional", arch=arch, volume=volume)
    assert run.samples < n**3 // 4  # 64 rays, far fewer samples than voxels
    per_slice = -(-(n * n) // arch.pipelines) + arch.slice_overhead_cycles
    assert run.cycles == n * per_slice + pipeline_latency(scene, modulates=False)
    cycle = render(scene, fidelity="cycle", arch=arch, volume=volume)
    # VolumePro 1000 skips beams no ray reaches (docs/cycle.md), so the estimate, which
    # streams whole slices, bounds it from above; shrinking slices to the rays used to
    # put the estimate ~90 % below it.
    assert 0.6 * run.cycles < cycle.cycles <= run.cycles
