"""The ``cycle`` rung on the Cube-4 family: bit-identical images, exact cycle accounting.

Design section 3: functional, transaction, cycle and rtl images are bit-identical for the
same scene and architecture.  The cycle image is assembled only from what the modelled
pixel bus delivers (see test_cycle_faults.py for the proof by fault injection).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs
from rungs import assert_identical, functional_and_cycle, scene_of

from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import TransferSpec
from hwsim.volumes import make_phantom, read_volume
from hwsim.volumes.volume import Volume
from models.machines.cube4.cycle import UNITS
from models.units import skew

pytestmark = pytest.mark.model

VIEWS = [(0, 0), (45, 0), (0, 90), (30, 20), (180, 0), (37, -61), (90, 45)]
MODES = ["composite", "mip", "minip", "xray", "iso"]


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=21)  # odd, not a multiple of P


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize(("az", "el"), VIEWS)
def test_cycle_equals_functional_bit_for_bit_parallel(head, mode, az, el):
    fixed, cycle, _ = functional_and_cycle(scene_of(az, el, mode=mode), head, "cube4")
    assert_identical(fixed, cycle)
    if mode == "composite":
        assert cycle.image[..., 3].max() > 0.5  # not a trivially empty picture


@pytest.mark.parametrize("mode", ["composite", "mip", "xray", "iso"])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20), (45, 0), (150, -30)])
def test_cycle_equals_functional_bit_for_bit_perspective(head, mode, az, el):
    scene = scene_of(az, el, mode=mode, projection="perspective")
    fixed, cycle, _ = functional_and_cycle(scene, head, "cube4")
    assert_identical(fixed, cycle)


@pytest.mark.parametrize("pipelines", [1, 3, 8])
def test_any_pipeline_count_renders_the_same_image(head, pipelines):
    arch = dataclasses.replace(resolve_arch("cube4"), pipelines=pipelines)
    fixed, cycle, _ = functional_and_cycle(scene_of(60, 25), head, arch)
    assert_identical(fixed, cycle)
    assert cycle.counters["memory.conflicts"] == 0


def test_non_cubic_anisotropic_volume(rng):
    data = (rng.random((9, 14, 23)) * 3000).astype(np.uint16)
    data[3:7, 4:10, 5:18] += 900
    vol = Volume(data=data, spacing=(2.0, 1.0, 0.7), bits=12, name="box")
    for az, el in [(20, 10), (100, 0), (0, 80)]:
        assert_identical(
            *functional_and_cycle(
                scene_of(az, el, transfer=TransferSpec(preset="auto")), vol, "cube4"
            )[:2]
        )


@pytest.mark.parametrize(
    "extra", list(rungs.FEATURE_VARIANTS.values()), ids=list(rungs.FEATURE_VARIANTS)
)
def test_scene_features_stay_bit_identical(head, extra):
    assert_identical(*functional_and_cycle(scene_of(40, 15, **extra), head, "cube4")[:2])


def test_marschner_lobb_and_ball():
    for name in ("marschner-lobb", "ball"):
        vol = make_phantom(name, size=24)
        for mode in ("composite", "mip"):
            tf = TransferSpec(preset="auto")
            assert_identical(
                *functional_and_cycle(scene_of(25, 35, mode=mode, transfer=tf), vol, "cube4")[:2]
            )


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ct_cranium.nrrd", "mr_brainsmall.nrrd"])
def test_real_volumes_are_bit_identical(shared_data, name):
    vol = read_volume(shared_data / name)
    for mode, view in (("composite", (30, 15)), ("mip", (90, 0))):
        scene = scene_of(*view, size=40, mode=mode, transfer=TransferSpec(preset="auto"))
        assert_identical(*functional_and_cycle(scene, vol, "cube4")[:2])


def test_counters_add_up_and_throughput_never_exceeds_P(head):
    fixed, cycle, plan = functional_and_cycle(scene_of(33, 21), head, "cube4")
    c, P = cycle.counters, 4
    units = [u for u in ["memory", *cycle.elaborated_units] if u not in ("ring", "pixel_bus")]
    rungs.assert_slice_counters_add_up(cycle, plan, P, units)
    reads = sum(c[f"memory.module[{m}].reads"] for m in range(P))
    assert reads == head.data.size  # every voxel read exactly once per frame
    moved = sum(c[f"pipeline[{m}].memory.o.transfers"] for m in range(P))
    assert moved == reads and c["pipeline[0].memory.o.stall_cycles"] == 0


def test_axis_aligned_cycle_count_has_its_closed_form():
    """Timing rules of docs/cycle.md: the prime slice and n - 1 slices of n ceil(n / P)
    clocks; the last slice's first pixels leave the pipeline latency later (address
    skew.LATENCY, slice-buffer read 1, beam alignment C + 1, gradient look-ahead C,
    Cube-4's units, the pixel FIFO's write 1) and the bus drains every ray one per clock
    (P arrive per clock)."""
    n, P = 16, 4
    vol = make_phantom("head", size=n)
    fixed, cycle, plan = functional_and_cycle(scene_of(0, 0, size=n), vol, "cube4")
    C = -(-n // P)
    units = ("interp", "gradient", "classify", "shade", "composite")  # no crop on Cube-4
    assert skew.LATENCY == 3  # the skew unit's three stages (issue 34)
    latency = skew.LATENCY + 1 + (C + 1) + C + sum(UNITS[u].LATENCY for u in units) + 1
    rays = plan.ray_ids.size  # all finish on the last slice; the bus drains one per clock
    assert cycle.cycles == n * n * C + latency + rays
    assert cycle.counters["pipeline.latency_cycles"] == latency


def test_a_small_pixel_fifo_costs_cycles_not_pixels(head):
    scene = scene_of(30, 20)
    fixed, roomy, _ = functional_and_cycle(scene, head, "cube4")
    from models.machines.cube4.cycle import Faults

    _, tight, _ = functional_and_cycle(scene, head, "cube4", faults=Faults(pixel_fifo_depth=8))
    assert np.array_equal(tight.image, roomy.image)
    assert tight.cycles > roomy.cycles
    stalls = tight.counters["pipeline[0].composite.stall_cycles"]
    assert (
        stalls > 0
        and tight.cycles - roomy.cycles <= stalls + roomy.counters["pixel_bus.drain_cycles"]
    )


def test_render_entry_point_reports_cycle_stats(head):
    run = render(scene_of(30, 20), fidelity="cycle", arch="cube4", volume=head)
    assert run.cycles > 0 and run.clock_hz == 125e6
    assert run.derived["samples_per_cycle"] <= 4
    assert "memory" in run.elaborated_units and "crop" in run.elided_units


def test_perspective_rays_denser_than_voxels_stretch_slices_not_the_rules():
    """Timing rule 3: a pipeline owing more samples than a slice has clocks stretches the
    slice; every unit still accounts each cycle exactly once and samples/cycle <= P."""
    vol = make_phantom("head", size=12)
    scene = scene_of(20, 10, size=64, projection="perspective")
    fixed, cycle, plan = functional_and_cycle(scene, vol, "cube4")
    assert_identical(fixed, cycle)
    n, P = 12, 4
    T = n * -(-n // P)
    plain = (n + 1) * T + cycle.counters["pipeline.latency_cycles"]
    assert cycle.cycles > plain + cycle.counters["pixel_bus.drain_cycles"]
    assert cycle.samples <= P * cycle.cycles
    busy = [cycle.counters[f"pipeline[{m}].interp.busy_cycles"] for m in range(P)]
    assert max(busy) > n * T  # more samples than the frame's voxel slots on one pipeline
