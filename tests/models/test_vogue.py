"""VOGUE: whole host-defined rays on autonomous modules, the volume circulating on a ring.

The functional and cycle images are bit-identical (the cycle rung's pixels are the shared
back end's: what it adds is the timing); the transaction rung's cycles (work spread
evenly, the ring at its mean load) are within 2 % of the cycle rung's (rays dispatched
one by one, each link's bytes from the boards' slabs).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.golden import make_plan
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.figures import published_figures
from hwsim.studies.trade.independence import transaction_vs_cycle
from hwsim.volumes import load_volume, read_volume
from models.frame import frame_of
from models.machines.vogue.config import ring_link_bytes
from models.machines.vogue.cycle import module_loads
from models.machines.vogue.transaction import VogueTransaction
from tests.models.rungs import real_32, sized_phantom_scene

pytestmark = pytest.mark.model

RUNGS = ("functional", "transaction", "cycle")


scene_of = sized_phantom_scene


@pytest.fixture(scope="module")
def ct32(shared_data):
    return real_32(read_volume(shared_data / "ct_cranium.nrrd"), 22)


def rungs(scene, arch, volume=None):
    return {f: render(scene, fidelity=f, arch=arch, volume=volume) for f in RUNGS}


@pytest.mark.parametrize(
    ("arch", "projection", "mode"),
    [("vogue", "parallel", "composite"), ("vogue-64", "perspective", "mip")],
)
def test_a_real_32_cube_is_bit_identical_and_timed_within_2_percent(ct32, arch, projection, mode):
    runs = rungs(scene_of(projection=projection, mode=mode), arch, ct32)
    functional, transaction, cycle = (runs[f] for f in RUNGS)
    assert np.array_equal(cycle.image, functional.image)
    assert np.array_equal(transaction.image, functional.image)
    assert np.ptp(functional.image) > 0
    assert abs(transaction.cycles / cycle.cycles - 1) <= 0.02
    assert cycle.counters["modules.samples"] == functional.samples


def test_one_board_is_its_samples_plus_set_up():
    runs = rungs(scene_of(size=16), "vogue")
    c = runs["cycle"].counters
    assert c["ring.cycles"] == 0 and c["ring.bottleneck"] == 0
    expected = c["modules.samples"] + 4 * c["host.rays"] + c["pipeline.latency_cycles"]
    assert runs["cycle"].cycles == runs["transaction"].cycles == expected


def _with_ring(bytes_per_second):
    arch = resolve_arch("vogue-64")
    return dataclasses.replace(
        arch, buffers={**arch.buffers, "ring_bytes_per_second": bytes_per_second}
    )


def test_the_ring_binds_until_it_is_fast_enough():
    scene = scene_of(size=32)
    slow = render(scene, fidelity="cycle", arch=_with_ring(5.2e9))
    fast = render(scene, fidelity="cycle", arch=_with_ring(1e12))
    assert slow.counters["ring.bottleneck"] == 1 and fast.counters["ring.bottleneck"] == 0
    assert slow.cycles > fast.cycles
    c = fast.counters
    assert fast.cycles == c["modules.busiest_cycles"] + c["pipeline.latency_cycles"]
    assert np.array_equal(slow.image, fast.image)


def test_rays_go_to_the_module_free_first():
    assert module_loads(np.array([5, 1, 1, 1]), 2).tolist() == [5, 3]
    assert module_loads(np.array([2, 2, 2]), 4).tolist() == [2, 2, 2, 0]


def test_each_link_carries_every_slab_but_the_next_boards():
    scene = scene_of(size=8)
    volume = load_volume(scene.volume, scene.base_dir)
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), resolve_arch("vogue"))
    slab = 2 * 8 * 8 * 2  # two 8 x 8 slices of 16-bit voxels per board
    assert ring_link_bytes(frame, 4).tolist() == [3 * slab] * 4
    assert ring_link_bytes(frame, 1).tolist() == [0]


def test_a_plan_not_cast_from_the_image_is_refused():
    scene = scene_of(size=8)
    volume = load_volume(scene.volume, scene.base_dir)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, "shear-warp")
    with pytest.raises(InputError, match="pipeline.order: VOGUE casts host-defined rays"):
        VogueTransaction(frame_of(scene, volume, tf, resolve_arch("vogue"), plan))


def test_the_figures_and_the_independence_are_declared():
    (one,) = published_figures(resolve_arch("vogue"))
    (many,) = published_figures(resolve_arch("vogue-64"))
    assert (one.key, one.value, one.evidence, one.fitted_from) == (
        "fps_256",
        2.5,
        "fitted",
        ("pipeline.clock_hz",),
    )
    assert (many.key, many.value, many.evidence) == ("fps_512", 20.0, "fitted")
    assert set(many.fitted_from) == {"pipeline.count", "buffers.ring_bytes_per_second"}
    assert transaction_vs_cycle(resolve_arch("vogue")).verdict == "partly shared"
