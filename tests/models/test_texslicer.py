"""The texture slicer (models/machines/texslicer): 3-D textures sliced by view-aligned
planes and 2-D stacks chosen per view.  Cycle images bit-identical to the functional rung,
transaction cycles within the contract, the fill rate or memory as the bottleneck, and the
2-D stack's popping in the ladder's algorithmic error."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.golden.render import render_golden
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import VolumeSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom, read_volume
from tests.models.rungs import (
    FEATURE_VARIANTS,
    assert_identical,
    functional_and_cycle,
    machine,
    scene_of,
    within_contract,
)

pytestmark = pytest.mark.model

ARCHS = ("texture-slicer", "texture-slicer-2d")


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=24)


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize(
    ("mode", "projection", "view", "size"),
    [("composite", "parallel", (30, 20), 24), ("composite", "perspective", (200, -35), 48),
     ("mip", "parallel", (95, 10), 40), ("iso", "perspective", (30, 60), 24)],
)  # fmt: skip
def test_cycle_is_the_functional_image_and_transaction_within_contract(
    head, arch, mode, projection, view, size
):
    """Magnified views (48 and 40 pixels on 24^3) included: their first tiles fetch,
    their last ones only raster."""
    scene = scene_of(*view, mode=mode, projection=projection, size=size)
    fixed, cycle, _ = functional_and_cycle(scene, head, arch)
    assert_identical(fixed, cycle)
    exact, approx = within_contract(scene, head, arch)
    assert exact.counters["raster.fragments"] == approx.counters["raster.fragments"] > 0
    assert exact.counters["texture.lines"] == approx.counters["texture.lines"] > 0


@pytest.mark.parametrize("variant", ["pre-classified", "unlit", "gm-modulation"])
def test_features_stay_bit_identical(head, variant):
    extra = dict(FEATURE_VARIANTS[variant])
    render = extra.pop("render", None)
    scene = scene_of(40, 25, size=20, render=render, **extra)
    for arch in ARCHS:
        fixed, cycle, _ = functional_and_cycle(scene, head, arch)
        assert_identical(fixed, cycle)


def test_the_bottleneck_moves_from_memory_to_fill_rate(head):
    """Halving the memory's bytes per clock slows a memory-bound frame; with ample memory
    the frame is the fill rate: fragments x clocks per fragment over the pipelines."""
    scene = scene_of(30, 20, size=24)
    base = resolve_arch("texture-slicer")
    runs = {}
    for bpc in (8, 16, 4096):
        arch = machine(base, buffers={"memory_bytes_per_clock": bpc})
        runs[bpc] = functional_and_cycle(scene, head, arch)[1]
    assert runs[8].cycles > 1.5 * runs[16].cycles
    assert runs[8].counters["bottleneck.fill_tiles"] == 0
    fill = runs[4096]
    assert fill.counters["bottleneck.memory_tiles"] == 0
    c = fill.counters
    assert c["raster.busy_cycles"] >= c["raster.fragments"] * c["raster.fragment_clocks"] // 4


def test_post_classification_costs_a_texture_clock_on_one_unit():
    """Lit, post-classified 3-D: trilinear (2) + lookup (1) on 2 units = 2 clocks; the
    2-D stack's bilinear fetch and lookup fit one."""
    head = make_phantom("head", size=16)
    scene = scene_of(30, 20, size=16)
    clocks = {a: functional_and_cycle(scene, head, a)[1].counters["raster.fragment_clocks"]
              for a in ARCHS}  # fmt: skip
    assert clocks == {"texture-slicer": 2, "texture-slicer-2d": 1}


def test_stack_switching_pops_in_the_algorithmic_error():
    """Across 45 degrees the 2-D machine switches stacks: a 0.2 degree turn there changes
    its image several times more than the same turn elsewhere, and than the 3-D machine's
    (view-aligned slices).  The jump is in golden at the machine's positions: the ladder's
    algorithmic error, not the datapath's."""
    vol = make_phantom("head", size=32)

    def golden(arch, az):
        scene = scene_of(az, 0, size=32)
        tf = resolve_transfer(scene.transfer, vol)
        return render_golden(scene, vol, tf, sampling=resolve_arch(arch).order).image

    def turn(arch, az):
        return float(np.abs(golden(arch, az - 0.1) - golden(arch, az + 0.1)).mean())

    jump_2d = turn("texture-slicer-2d", 45.0)
    assert jump_2d > 2 * turn("texture-slicer-2d", 41.0)
    assert jump_2d > 4 * turn("texture-slicer", 45.0)


def test_a_stack_mismatched_with_its_order_is_refused(tmp_path):
    text = Path(resolve_arch("texture-slicer").source).read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('textures = "3d"', 'textures = "2d"'))
    with pytest.raises(InputError, match="pipeline.order.*shear-image"):
        resolve_arch(str(bad))


@pytest.mark.parametrize("fidelity", ["functional", "transaction", "cycle"])
def test_early_termination_is_refused_as_the_machine_never_had_it(fidelity):
    volume = VolumeSpec(phantom="head", params=(("size", 16),))
    scene = scene_of(30, 20, size=16, volume=volume, render={"early_termination": 0.9})
    with pytest.raises(InputError, match="early_termination"):
        render(scene, fidelity=fidelity, arch=resolve_arch("texture-slicer"))


def test_renders_the_real_ct_at_every_rung(shared_data):
    """Acceptance: a 32^3 crop of the CT skull at functional, transaction and cycle."""
    ct = read_volume(shared_data / "ct_cranium.nrrd")
    data = np.ascontiguousarray(ct.data[::3, ::8, ::8][:32])
    vol = dataclasses.replace(ct, data=data, spacing=(4.5, 7.656, 7.656))
    assert vol.shape == (32, 32, 32)
    scene = scene_of(30, 20, size=32)
    fixed, cycle, _ = functional_and_cycle(scene, vol, "texture-slicer")
    assert_identical(fixed, cycle)
    within_contract(scene, vol, "texture-slicer")
