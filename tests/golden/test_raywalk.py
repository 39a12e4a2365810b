"""The compiled golden ray walk renders the step engine's image bit for bit, on every
feature it takes, on any number of threads; everything else still takes the step engine."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from golden_helpers import gaussian_volume, make_scene

from hwsim.core.threads import THREADS_ENV_VAR
from hwsim.golden import raywalk
from hwsim.golden import render as golden_render
from hwsim.golden.sampling import interleave, voxel_gradients
from hwsim.spec.scene import CropSpec, Light, Material
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume

pytestmark = pytest.mark.golden


def _ramp_tf(hi: float, **extra) -> TransferFunction:
    """Colour and opacity varying over the value range, with a step (two control points
    at one value) and a transparent start."""
    values = np.array([0.0, 0.1 * hi, 0.3 * hi, 0.3 * hi, 0.7 * hi, hi])
    rgba = np.array(
        [
            [0.0, 0.0, 0.0, 0.0],
            [0.9, 0.2, 0.1, 0.0],
            [0.8, 0.5, 0.2, 0.05],
            [0.3, 0.6, 0.9, 0.2],
            [1.0, 1.0, 0.7, 0.6],
            [1.0, 1.0, 1.0, 0.9],
        ]
    )
    return TransferFunction(values=values, rgba=rgba, **extra)


def _both(scene, volume, tf, threads="2", monkeypatch=None):
    if monkeypatch is not None:
        monkeypatch.setenv(THREADS_ENV_VAR, threads)
    compiled = golden_render.render_golden(scene, volume, tf)
    steps = golden_render.render_golden(scene, volume, tf, compiled=False)
    return compiled, steps


_TWO_LIGHTS = (Light(direction=(-0.4, 0.5, 1.0)), Light(direction=(0.6, -0.2, 0.5), intensity=0.5))
_CASES = {
    "lit": ({}, {}),
    "unlit": ({"lights": ()}, {}),
    "early termination": ({"early_termination": 0.8}, {}),
    "half steps": ({"sample_spacing": 0.5}, {}),
    "lighting off": ({"lighting": False}, {}),
    "perspective": ({"projection": "perspective", "zoom": 1.5}, {}),
    "two lights": ({"lights": _TWO_LIGHTS}, {}),
    "modulated": ({}, {"gradient_points": np.array([[0.0, 0.2], [30.0, 1.0]])}),
    "illumination": ({}, {"illumination_points": np.array([[0.0, 0.0], [20.0, 1.0]])}),
}


@pytest.mark.parametrize("case", list(_CASES), ids=list(_CASES))
def test_the_compiled_walk_is_the_step_engine_bit_for_bit(case, monkeypatch):
    scene_kw, tf_kw = _CASES[case]
    volume = gaussian_volume((30, 34, 38), spacing=(1.5, 0.9, 1.0))
    scene = make_scene(az=33, el=21, size=40, **scene_kw)
    tf = _ramp_tf(1000.0, **tf_kw)
    assert raywalk.eligible(golden_render._Renderer(scene, volume, tf, _plan(scene, volume, tf)))
    compiled, steps = _both(scene, volume, tf, monkeypatch=monkeypatch)
    assert np.array_equal(compiled.image, steps.image)
    assert (compiled.samples, compiled.rays) == (steps.samples, steps.rays)
    assert compiled.image[..., 3].max() > 0.1  # the scene shows something


@pytest.mark.parametrize("shininess", [1.0, 2.0, 0.5, 7.3, 24.0])
def test_every_shininess_gives_the_same_bits(shininess, monkeypatch):
    volume = make_phantom("head", size=40)
    scene = dataclasses.replace(
        make_scene(az=200, el=-35, size=48),
        material=Material(ambient=0.1, diffuse=0.6, specular=0.5, shininess=shininess),
    )
    hi = float(volume.value_range[1])
    compiled, steps = _both(scene, volume, _ramp_tf(hi), monkeypatch=monkeypatch)
    assert np.array_equal(compiled.image, steps.image)


@pytest.mark.parametrize("threads", ["1", "2", "3"])
def test_the_thread_count_does_not_change_a_bit(threads, monkeypatch):
    volume = make_phantom("head", size=48)
    scene = make_scene(az=30, el=15, size=96, early_termination=0.95)
    tf = _ramp_tf(float(volume.value_range[1]))
    monkeypatch.setenv(THREADS_ENV_VAR, "1")
    one = golden_render.render_golden(scene, volume, tf)
    monkeypatch.setenv(THREADS_ENV_VAR, threads)
    many = golden_render.render_golden(scene, volume, tf)
    assert np.array_equal(one.image, many.image) and one.samples == many.samples


def test_a_volume_one_voxel_thick_on_an_axis():
    data = np.linspace(0.0, 1000.0, 5 * 7).reshape(1, 5, 7)
    volume = Volume(data=data, spacing=(1.0, 1.0, 1.0))
    scene = make_scene(az=10, el=80, size=16)
    compiled, steps = _both(scene, volume, _ramp_tf(1000.0))
    assert np.array_equal(compiled.image, steps.image) and compiled.samples > 0


@pytest.mark.parametrize(
    "change",
    [
        {"sampling": "shear-warp"},
        {"mode": "mip"},
        {"interpolation": "cubic"},
        {"blend_order": "back-to-front"},
        {"crop": CropSpec(x=(5.0, 20.0))},
        {"order": "pre"},
    ],
    ids=["shear-warp", "mip", "cubic", "back-to-front", "crop", "pre-classified"],
)
def test_other_scenes_take_the_step_engine(change):
    volume = gaussian_volume(24)
    sampling = change.pop("sampling", "ray")
    crop = change.pop("crop", None)
    order = change.pop("order", "post")
    scene = make_scene(size=24, **change)
    if crop is not None:
        scene = dataclasses.replace(scene, crop=crop)
    tf = dataclasses.replace(_ramp_tf(1000.0), order=order)
    plan = golden_render.make_plan(scene, volume, sampling)
    assert not raywalk.eligible(golden_render._Renderer(scene, volume, tf, plan))


def test_interleaved_rows_are_numpy_gradient_bit_for_bit():
    rng = np.random.default_rng(5)
    for shape, spacing, dtype in [
        ((9, 11, 13), (1.5, 0.957, 0.957), np.int16),
        ((1, 4, 6), (1.0, 2.0, 0.5), np.uint8),
        ((5, 1, 2), (0.3, 1.0, 1.7), np.float32),
    ]:
        data = (rng.random(shape) * 200 - 50).astype(dtype)
        rows = interleave(data, spacing)
        assert np.array_equal(rows[:, 0], data.astype(np.float64).ravel())
        for c, g in enumerate(voxel_gradients(data, spacing), start=1):
            assert np.array_equal(rows[:, c], g), (shape, c)


def _plan(scene, volume, tf):
    occupancy = golden_render.occupancy_for(scene, volume, tf)
    return golden_render.make_plan(scene, volume, "ray", occupancy=occupancy)
