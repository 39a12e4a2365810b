"""Simulator tier of the Cube-4 RTL top: whole frames on Icarus and on Verilator (the
testbench runs the frame by itself, no Python per clock), image
bit-identical to the cycle rung and the same cycle count, on both Cube-4 architectures
and several views, unlit (composite, MIP) and lit (gradients from neighbouring samples,
Phong, gradient-opacity modulation); with a back-pressured pixel bus the image stays and
only the count grows; a corrupted voxel load changes the image (the image is the
hardware's).  Every case runs on Verilator; Icarus (about four times slower per frame)
runs one unlit and one lit case and the back-pressured bus.

Builds go to ``build/rtl/<simulator>_top_P<P>_<key>/`` (one per simulator and
configuration, reused while the RTL sources do not change).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simulators import require
from top_cases import LIT_CASES, TOP_CASES, case

from rtl.rung import run_simulator

pytestmark = pytest.mark.cosim
SIMULATORS = ["verilator", "icarus"]


#: (case, simulator): every case on Verilator, one unlit and one lit on Icarus.
FRAMES = [(key, "verilator") for key in TOP_CASES + LIT_CASES] + [
    (TOP_CASES[2], "icarus"),
    (LIT_CASES[0], "icarus"),
]


@pytest.mark.parametrize(
    ("key", "sim"), FRAMES, ids=lambda k: "-".join(map(str, k)) if isinstance(k, tuple) else k
)
def test_top_frame_equals_cycle_rung(key, sim):
    require(sim)
    program, reference = case(*key)
    result, timing = run_simulator(program, sim)
    assert np.array_equal(result.image, reference.image), "RTL image differs from cycle rung"
    assert result.cycles == reference.cycles
    assert result.samples == reference.samples
    assert result.rays == reference.rays
    if key[3] in ("composite", "lit"):
        assert reference.image[..., 3].max() > 0.5  # not an empty picture
    assert timing["clocks"] > result.cycles


def test_lit_frame_differs_from_the_unlit_one():
    """The gradient and shader path really shades: the same view unlit is another image
    (and the same cycle count: the hardware is the same for every scene)."""
    lit_program, lit = case("cube4", 30, 20, "lit", 8)
    _, unlit = case("cube4", 30, 20, "composite", 8)
    assert not np.array_equal(lit.image, unlit.image)
    assert lit.cycles == unlit.cycles
    assert lit_program.registers["lit"] == 1


def test_top_gradient_opacity_modulation_equals_cycle_rung():
    require("verilator")
    program, reference = case("cube4-teramac", 30, 20, "lit", 8, modulate=True)
    _, plain = case("cube4-teramac", 30, 20, "lit", 8)
    assert not np.array_equal(reference.image, plain.image)  # modulation changes opacity
    result, _ = run_simulator(program, "verilator")
    assert program.registers["modulate"] == 1
    assert np.array_equal(result.image, reference.image)
    assert (result.cycles, result.samples) == (reference.cycles, reference.samples)


def test_top_anisotropic_volume_equals_cycle_rung():
    """The gradient's to_world ratios (min spacing / spacing per axis, UQ1.12) in RTL."""
    require("verilator")
    program, reference = case("cube4", 30, 20, "lit", 8, spacing=(1.5, 1.0, 0.75))
    _, iso = case("cube4", 30, 20, "lit", 8)
    assert not np.array_equal(reference.image, iso.image)
    result, _ = run_simulator(program, "verilator")
    assert np.array_equal(result.image, reference.image)
    assert (result.cycles, result.samples) == (reference.cycles, reference.samples)


@pytest.mark.parametrize("sim", SIMULATORS)
def test_top_pixel_backpressure_keeps_the_image(sim):
    require(sim)
    program, reference = case("cube4", 30, 20, "lit", 8)
    result, _ = run_simulator(program, sim, stall_every=3)
    assert np.array_equal(result.image, reference.image)
    assert result.samples == reference.samples
    # Every third clock refused: the bus needs more clocks than the free-running frame.
    assert result.cycles > reference.cycles


@pytest.mark.parametrize("depth", [1, 5])
def test_top_shallow_pixel_fifo_stalls_like_the_cycle_rung(depth):
    """Timing rule 4 in the top: a pixel FIFO smaller than the frame's rays freezes the
    core in the clocks a push finds it full, as the cycle rung's rule; cycles, not
    pixels, and the same frozen clocks."""
    require("verilator")
    program, reference = case("cube4", 30, 20, "lit", 8, pixel_fifo=depth)
    _, roomy = case("cube4", 30, 20, "lit", 8)
    assert reference.cycles > roomy.cycles  # the cycle rung does stall here
    assert program.registers["fifo_depth"] == depth
    result, _ = run_simulator(program, "verilator")
    assert np.array_equal(result.image, roomy.image)
    assert (result.cycles, result.samples) == (reference.cycles, reference.samples)
    frozen = result.counters["pixel_bus.stall_cycles"]
    assert frozen > 0 and frozen == reference.counters["pixel_bus.stall_cycles"]


def test_top_image_comes_from_the_loaded_volume():
    require("verilator")
    program, reference = case("cube4", 30, 20, "mip", 12)
    words = list(program.volume_words)
    # Word 150 of the voxel memory (outside the chip): all P voxels set to full scale.
    words[150] = (1 << (program.geo.pipelines * program.dp.voxel_bits)) - 1
    broken = dataclasses.replace(program, volume_words=words)
    result, _ = run_simulator(broken, "verilator")
    assert not np.array_equal(result.image, reference.image)
    assert result.cycles == reference.cycles  # the data changed, not the timing


def test_top_early_ray_termination_equals_cycle_rung():
    require("verilator")
    program, reference = case("cube4", 30, 20, "lit", 12, early_termination=0.5)
    _, full = case("cube4", 30, 20, "lit", 12)
    assert reference.samples < full.samples  # rays do terminate in this scene
    result, _ = run_simulator(program, "verilator")
    assert np.array_equal(result.image, reference.image)
    assert result.samples == reference.samples and result.cycles == reference.cycles


#: Views at exactly 45 degrees (sample positions on half-voxel diagonals), the body
#: diagonal, and along each axis in both directions.
EXACT_VIEWS = [
    ("cube4", 45, 0, "lit", 12),
    ("cube4", 0, 45, "lit", 12),
    ("cube4", 45, 45, "lit", 12),
    ("cube4", 135, 0, "lit", 12),
    ("cube4", 45, 35.26438968, "lit", 12),
    ("cube4-teramac", -45, 0, "mip", 10),
    ("cube4", 180, 0, "lit", 12),
    ("cube4", 270, 0, "composite", 12),
    ("cube4", 0, -90, "lit", 12),
]


@pytest.mark.parametrize("key", EXACT_VIEWS, ids=lambda k: "-".join(map(str, k)))
def test_top_exact_and_axis_views_equal_cycle_rung(key):
    require("verilator")
    program, reference = case(*key)
    result, _ = run_simulator(program, "verilator")
    assert np.array_equal(result.image, reference.image)
    assert (result.cycles, result.samples) == (reference.cycles, reference.samples)
