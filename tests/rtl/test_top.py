"""Amaranth-simulator tier of the Cube-4 RTL top: tiny frames end to end (unlit and lit:
gradients from neighbouring samples and Phong shading), bit-identical to the cycle rung
with the same cycle count; what the top refuses, with the key named.

Amaranth's simulator takes ~20 s for one lit 8^3 frame of the whole top (the ~9 500
table loads dominate), so this tier runs few frames; the cocotb tier runs the matrix."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from top_cases import scene_of

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import CutPlane, Light
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of
from rtl.amaranth_run import run_amaranth
from rtl.frame import prepare

pytestmark = pytest.mark.rtl


def _amaranth_case(arch: str, az: float, el: float, mode: str, size: int, pipelines=None):
    """``(program, cycle-rung reference)`` with the top sized for the volume (``max_axis =
    size``: the same hardware for this frame, and faster to simulate)."""
    scene = scene_of(az, el, mode)
    volume = make_phantom("head", size=size)
    machine = resolve_arch(arch)
    if pipelines is not None:
        machine = dataclasses.replace(machine, pipelines=pipelines)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    from models.cycle import render_cycle

    reference = render_cycle(frame_of(scene, volume, tf, machine, plan))
    return prepare(frame_of(scene, volume, tf, machine, plan), max_axis=size), reference


def test_lit_top_in_amaranth_equals_cycle_rung():
    program, reference = _amaranth_case("cube4", 30, 20, "lit", 8)
    result = run_amaranth(program)
    assert np.array_equal(result.image, reference.image)
    assert result.cycles == reference.cycles
    assert result.samples == reference.samples


def test_top_in_amaranth_keeps_the_image_under_pixel_backpressure():
    """MIP in decreasing slice order (few table loads: fast here; the lit frame under
    backpressure runs on both simulators in the cocotb tier)."""
    program, reference = _amaranth_case("cube4-teramac", 180, 0, "mip", 8)
    result = run_amaranth(program, stall_every=2)
    assert np.array_equal(result.image, reference.image)
    # A refused bus delays the last pixel; the frame itself is the same.
    assert result.cycles > reference.cycles
    assert result.samples == reference.samples


def _prepare(scene, size=8, arch="cube4"):
    volume = make_phantom("head", size=size)
    machine = resolve_arch(arch)
    tf = resolve_transfer(scene.transfer, volume)
    return prepare(frame_of(scene, volume, tf, machine, make_plan(scene, volume, machine.order)))


@pytest.mark.parametrize(
    ("scene", "size", "key"),
    [
        (scene_of(0, 0, "mip"), 129, "volume"),
        (scene_of(0, 0, "xray"), 8, "render.mode"),
        (scene_of(0, 0, "composite").replace(cut_planes=(CutPlane(),)), 8, "cut_planes"),
        (scene_of(0, 0, "lit").replace(lights=(Light(),) * 3), 8, "lights"),
        (
            scene_of(0, 0, "lit").replace(
                transfer=dataclasses.replace(scene_of(0, 0, "lit").transfer, order="pre")
            ),
            8,
            "transfer.order",
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
    from hwsim.cli.commands import main

    argv = ["rtl", "build", "top", "--set", "top.pipelines=2", "--set", "top.max_axis=8"]
    assert main([*argv, "--out", str(tmp_path), "--no-synth", "--quiet"]) == 0
    text = (tmp_path / "top.v").read_text()
    assert "module top(" in text.replace(" (", "(")
    for port in ("load__payload", "pixel__payload", "pixel__ready", "cycles", "done"):
        assert port in text


def test_rtl_rung_trace_writes_the_tops_waveform(tmp_path):
    from hwsim.run.fidelity import render

    scene = scene_of(30, 20, "mip", image=8)
    head = make_phantom("head", size=8)
    # Every signal of the whole top goes into the VCD: a tiny 5^3 frame (the centre of
    # the head phantom).
    volume = dataclasses.replace(head, data=np.ascontiguousarray(head.data[2:7, 2:7, 2:7]))
    vcd = tmp_path / "top.vcd"
    run = render(scene, fidelity="rtl", arch="cube4", volume=volume, trace=vcd)
    ref = render(scene, fidelity="cycle", arch="cube4", volume=volume)
    assert np.array_equal(run.image, ref.image) and run.cycles == ref.cycles
    assert run.counters["rtl.simulator"] == "amaranth"
    text = vcd.read_text()
    assert "pixel__valid" in text and "$enddefinitions" in text


@pytest.mark.parametrize(
    ("pipelines", "size", "az", "el", "mode"),
    [(1, 8, 30, 20, "lit"), (3, 9, 30, 20, "lit"), (5, 8, 90, 0, "mip")],
)
def test_top_with_any_pipeline_count_equals_cycle_rung(pipelines, size, az, el, mode):
    """P = 1 (no links: every neighbour is the pipeline's own) and counts that are not
    powers of two (mod and div by P; the ring's neighbours at both ends)."""
    program, reference = _amaranth_case("cube4", az, el, mode, size, pipelines)
    result = run_amaranth(program)
    assert np.array_equal(result.image, reference.image)
    assert (result.cycles, result.samples) == (reference.cycles, reference.samples)


def test_top_refuses_a_pixel_fifo_that_never_accepts_a_pixel():
    scene = scene_of(30, 20, "lit")
    volume = make_phantom("head", size=8)
    arch = dataclasses.replace(resolve_arch("cube4"), buffers={"pixel_fifo_entries": 0})
    tf = resolve_transfer(scene.transfer, volume)
    with pytest.raises(InputError) as info:
        prepare(frame_of(scene, volume, tf, arch, make_plan(scene, volume, arch.order)))
    assert info.value.key == "buffers.pixel_fifo_entries"
