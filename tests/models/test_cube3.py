"""Cube-3: skewed memory, barrel-shifter network, parallel units, a compositing tree.

The functional and cycle images are bit-identical (the cycle rung renders what its
network delivered, so a faulty shifter breaks the equality); the transaction rung (equal
slabs, max-plus closed form) is within 2 % of the cycle rung (per-slab samples, the
slab-by-slab recurrence), whichever of memory and units binds.
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
from models.backend import Backend
from models.frame import frame_of
from models.functional import render_functional
from models.machines.common.skewed import CubicFrameBuffer
from models.machines.cube3.cycle import Cube3Machine
from models.machines.cube3.frame import Cube3Faults, slab_schedule
from models.machines.cube3.network import deliver_volume
from models.machines.cube3.transaction import Cube3Transaction
from tests.models.rungs import real_32, sized_phantom_scene

pytestmark = pytest.mark.model

RUNGS = ("functional", "transaction", "cycle")


scene_of = sized_phantom_scene


def cube3(modules=512, units=512):
    return dataclasses.replace(resolve_arch("cube3"), pipelines=modules, buffers={"units": units})


@pytest.fixture(scope="module")
def mr32(shared_data):
    return real_32(read_volume(shared_data / "mr_brainsmall.nrrd"), 10)


@pytest.mark.parametrize(
    ("projection", "mode", "modules", "units"),
    [("perspective", "composite", 512, 512), ("parallel", "mip", 16, 4)],
)
def test_a_real_32_cube_is_bit_identical_and_timed_within_2_percent(
    mr32, projection, mode, modules, units
):
    arch = cube3(modules, units)
    runs = {f: render(scene_of((200, 30), projection, mode), fidelity=f, arch=arch, volume=mr32)
            for f in RUNGS}  # fmt: skip
    functional, transaction, cycle = (runs[f] for f in RUNGS)
    assert np.array_equal(cycle.image, functional.image)
    assert np.array_equal(transaction.image, functional.image)
    assert np.ptp(functional.image) > 0
    assert abs(transaction.cycles / cycle.cycles - 1) <= 0.02
    assert cycle.counters["units.samples"] == functional.samples


def test_memory_or_units_bind():
    """512 modules read a 32-voxel row a clock: the units wait; 4 units: the memory waits."""
    scene = scene_of(size=32)
    wide = render(scene, fidelity="cycle", arch=cube3(512, 512)).counters
    narrow = render(scene, fidelity="cycle", arch=cube3(512, 4)).counters
    assert wide["units.wait_cycles"] > wide["units.busy_cycles"]
    assert narrow["units.busy_cycles"] > narrow["units.wait_cycles"]
    assert (
        wide["memory.beams_per_slice"] == 32
        and render(scene, fidelity="cycle", arch=cube3(16, 512)).counters["memory.beams_per_slice"]
        == 64
    )


def test_the_shifter_undoes_the_skew_and_a_faulty_one_shows():
    data = np.arange(6 * 7 * 8, dtype=np.uint16).reshape(6, 7, 8)
    for kp in range(3):
        for n in (4, 8, 16):
            delivered, _, _ = deliver_volume(CubicFrameBuffer.write(data, n), kp)
            assert np.array_equal(delivered, data)
    broken, _, _ = deliver_volume(CubicFrameBuffer.write(data, 8), 0, shifter_offset=1)
    assert not np.array_equal(broken, data)
    scene = scene_of(size=16)
    volume = load_volume(scene.volume, scene.base_dir)
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), cube3(8, 8))
    good = render_functional(frame).image
    assert np.array_equal(Cube3Machine(Backend(frame)).run().image, good)
    faulty = Cube3Machine(Backend(frame), faults=Cube3Faults(shifter_offset=1)).run()
    assert not np.array_equal(faulty.image, good)


def test_the_slab_recurrence():
    """Slab k waits for slice k + 2; the units take ceil(load / units) clocks a slab."""
    arrivals = np.array([10, 20, 30, 40])
    assert slab_schedule(np.array([8, 8, 8, 8]), arrivals, 4) == (30 + 2 + 10 + 2 + 2, 30 + 8)
    assert slab_schedule(np.array([80, 0, 0, 0]), arrivals, 4) == (50, 30)


def test_a_plan_not_cast_along_rays_is_refused():
    scene = scene_of(size=8)
    volume = load_volume(scene.volume, scene.base_dir)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, "shear-warp")
    with pytest.raises(InputError, match="pipeline.order: Cube-3 casts rays"):
        Cube3Transaction(frame_of(scene, volume, tf, resolve_arch("cube3"), plan))


def test_the_figure_and_the_independence_are_declared():
    (fig,) = published_figures(resolve_arch("cube3"))
    assert (fig.key, fig.value, fig.evidence, fig.fitted_from) == (
        "fps_512",
        30.0,
        "prediction",
        (),
    )
    assert transaction_vs_cycle(resolve_arch("cube3")).verdict == "partly shared"
