"""VIRIM (models/machines/virim): boards of a table-driven resampler and programmable ray
casters.  Cycle images bit-identical to the functional rung, transaction cycles within
the contract, the board count and the ray casters as the limit, and the weight table's
coarseness in the ladder's error."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.golden.render import render_golden
from hwsim.numerics import psnr
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


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=24)


@pytest.mark.parametrize(
    ("projection", "view", "size"),
    [("parallel", (30, 20), 32), ("perspective", (200, -35), 48), ("parallel", (95, 10), 40)],
)
def test_cycle_is_the_functional_image_and_transaction_within_contract(
    head, projection, view, size
):
    scene = scene_of(*view, projection=projection, size=size)
    fixed, cycle, _ = functional_and_cycle(scene, head, "virim")
    assert_identical(fixed, cycle)
    within_contract(scene, head, "virim")


@pytest.mark.parametrize("variant", ["pre-classified", "unlit", "gm-modulation"])
def test_features_stay_bit_identical(head, variant):
    extra = dict(FEATURE_VARIANTS[variant])
    rendering = extra.pop("render", None)
    scene = scene_of(40, 25, size=20, render=rendering, **extra)
    fixed, cycle, _ = functional_and_cycle(scene, head, "virim")
    assert_identical(fixed, cycle)


def test_boards_and_ray_casters_bind(head):
    """Half the boards: about twice the frame; with enough ray casters and ray buffers,
    the resampler (one sample a clock) binds instead, and the frame is the busiest
    board's samples."""
    scene = scene_of(30, 20, size=96)
    base = resolve_arch("virim")
    runs = {
        name: functional_and_cycle(scene, head, machine(base, **change))[1]
        for name, change in {
            "16": {},
            "8": {"pipelines": 8},
            "fast": {"buffers": {"raycasters": 8, "ray_buffers": 8}},
        }.items()
    }
    assert 1.8 < runs["8"].cycles / runs["16"].cycles < 2.2
    fast = runs["fast"]
    assert fast.cycles < runs["16"].cycles
    busiest = fast.counters["board.busiest_samples"]
    assert busiest <= fast.cycles <= busiest + 64
    assert fast.counters["board.busiest_samples"] >= fast.counters["board.mean_samples"]


def test_the_weight_table_costs_image_quality(head):
    """VIRIM's 16-entry weight table (interp.weight_bits = 4) against a 256-entry one:
    golden at the same positions is the same, the functional image drifts from it."""
    scene = scene_of(33, 21, size=24)
    coarse = functional_and_cycle(scene, head, "virim")[0]
    fine_arch = dataclasses.replace(
        resolve_arch("virim"), formats={**resolve_arch("virim").formats, "interp.weight_bits": 8}
    )
    fine = functional_and_cycle(scene, head, fine_arch)[0]
    tf = resolve_transfer(scene.transfer, head)
    golden = render_golden(scene, head, tf, sampling="ray").image
    assert psnr(golden, fine.image) > psnr(golden, coarse.image) + 3.0


@pytest.mark.parametrize("fidelity", ["functional", "transaction", "cycle"])
def test_mip_is_refused_as_the_machine_never_had_it(fidelity):
    volume = VolumeSpec(phantom="head", params=(("size", 16),))
    scene = scene_of(30, 20, size=16, volume=volume, mode="mip")
    with pytest.raises(InputError, match="render.mode"):
        render(scene, fidelity=fidelity, arch=resolve_arch("virim"))


def test_renders_the_real_mr_at_every_rung(shared_data):
    """Acceptance: a 32^3 cut of the MR head at functional, transaction and cycle."""
    mr = read_volume(shared_data / "mr_brainsmall.nrrd")
    data = np.ascontiguousarray(mr.data[10:74:2, ::4, ::4])
    vol = dataclasses.replace(mr, data=data, spacing=(2.0, 4.0, 4.0))
    assert vol.shape == (32, 32, 32)
    scene = scene_of(30, 20, size=32, preset="mr")
    fixed, cycle, _ = functional_and_cycle(scene, vol, "virim")
    assert_identical(fixed, cycle)
    within_contract(scene, vol, "virim")
