"""Amaranth-simulator tier of the Cube-4 RTL top: a tiny frame end to end, bit-identical
to the cycle rung with the same cycle count; what the top refuses, with the key named."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from top_cases import case, scene_of

from hwsim.errors import InputError, NotAvailableError
from hwsim.fidelity import resolve_arch
from hwsim.golden import make_plan
from hwsim.scene import CropSpec
from hwsim.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from rtl.amaranth_run import run_amaranth
from rtl.frame import prepare

pytestmark = pytest.mark.rtl


@pytest.mark.parametrize(
    "key",
    [("cube4", 0, 0, "mip", 8), ("cube4", 30, 20, "mip", 8), ("cube4-teramac", 45, 0, "mip", 8)],
)
def test_top_in_amaranth_equals_cycle_rung(key):
    program, reference = case(*key)
    result = run_amaranth(program)
    assert np.array_equal(result.image, reference.image)
    assert result.cycles == reference.cycles
    assert result.samples == reference.samples


def test_top_in_amaranth_composites_under_pixel_backpressure():
    program, reference = case("cube4-teramac", 30, 20, "composite", 8)
    result = run_amaranth(program, stall_every=2)
    assert np.array_equal(result.image, reference.image)
    assert reference.image[..., 3].max() > 0.5  # not an empty picture
    # A refused bus delays the last pixel; the frame itself is the same.
    assert result.cycles > reference.cycles
    assert result.samples == reference.samples


def _prepare(scene, size=8, arch="cube4"):
    volume = make_phantom("head", size=size)
    machine = resolve_arch(arch)
    tf = resolve_transfer(scene.transfer, volume)
    return prepare(scene, volume, tf, machine, make_plan(scene, volume, machine.order))


@pytest.mark.parametrize(
    ("scene", "size", "key"),
    [
        (scene_of(0, 0, "mip"), 17, "volume"),
        (scene_of(0, 0, "xray"), 8, "render.mode"),
        (dataclasses.replace(scene_of(0, 0, "composite"), crop=CropSpec(x=(0.0, 4.0))), 8, "crop"),
        (
            scene_of(0, 0, "composite").replace(
                render=dataclasses.replace(scene_of(0, 0, "composite").render, lighting=True)
            ),
            8,
            "lights",
        ),
        (
            scene_of(0, 0, "mip").replace(
                view=dataclasses.replace(scene_of(0, 0, "mip").view, projection="perspective")
            ),
            8,
            "view.projection",
        ),
    ],
)
def test_top_refuses_what_it_does_not_model_naming_the_key(scene, size, key):
    with pytest.raises(InputError) as info:
        _prepare(scene, size)
    assert info.value.key == key
    assert "\n" not in str(info.value)


def test_top_is_not_available_for_other_machines():
    with pytest.raises(NotAvailableError) as info:
        _prepare(scene_of(0, 0, "mip"), 8, arch="volumepro500")
    assert info.value.key == "--arch"


def test_rtl_build_top_writes_the_tops_verilog(tmp_path):
    from hwsim.cli import main

    argv = ["rtl", "build", "top", "--set", "top.pipelines=2", "--set", "top.max_axis=8"]
    assert main([*argv, "--out", str(tmp_path), "--no-synth", "--quiet"]) == 0
    text = (tmp_path / "top.v").read_text()
    assert "module top(" in text.replace(" (", "(")
    for port in ("load__payload", "pixel__payload", "pixel__ready", "cycles", "done"):
        assert port in text


def test_rtl_rung_trace_writes_the_tops_waveform(tmp_path):
    from hwsim.fidelity import render

    scene = scene_of(30, 20, "mip", image=8)
    volume = make_phantom("head", size=8)
    vcd = tmp_path / "top.vcd"
    run = render(scene, fidelity="rtl", arch="cube4", volume=volume, trace=vcd)
    ref = render(scene, fidelity="cycle", arch="cube4", volume=volume)
    assert np.array_equal(run.image, ref.image) and run.cycles == ref.cycles
    assert run.counters["rtl.simulator"] == "amaranth"
    text = vcd.read_text()
    assert "pixel__valid" in text and "$enddefinitions" in text


@pytest.mark.parametrize(
    ("pipelines", "size", "az", "el"),
    [(1, 8, 30, 20), (2, 9, 37, -61), (3, 10, 30, 20), (5, 8, 90, 0)],
)
def test_top_with_any_pipeline_count_equals_cycle_rung(pipelines, size, az, el):
    """P = 1 (no links), 2, and counts that are not powers of two (mod and div by P)."""
    scene = scene_of(az, el, "mip")
    volume = make_phantom("head", size=size)
    arch = dataclasses.replace(resolve_arch("cube4"), pipelines=pipelines)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, arch.order)
    from models.cycle import render_cycle

    reference = render_cycle(scene, volume, tf, arch, plan)
    result = run_amaranth(prepare(scene, volume, tf, arch, plan))
    assert np.array_equal(result.image, reference.image)
    assert (result.cycles, result.samples) == (reference.cycles, reference.samples)
