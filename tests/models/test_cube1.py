"""Cube-1: beams from the six axis views through the skewed cubic frame buffer.

The functional and cycle rungs' images are bit-identical (the cycle rung renders what its
modules deliver, so a stuck module breaks the equality); the transaction rung's cycles
(the skewing's theorem) equal the cycle rung's (the voxels' modules counted beam by beam).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.golden import make_plan
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.figures import published_figures
from hwsim.studies.trade.independence import transaction_vs_cycle
from hwsim.volumes import read_volume
from models.backend import Backend
from models.frame import frame_of
from models.functional import render_functional
from models.machines.cube1.cycle import Cube1Machine
from models.machines.cube1.frame import Cube1Faults

pytestmark = pytest.mark.model

RUNGS = ("functional", "transaction", "cycle")


def scene_of(view=(0, 0), mode="composite", size=16, phantom="head"):
    return Scene(
        volume=VolumeSpec(phantom=phantom, params=(("size", size),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=view[0], elevation=view[1], width=size, height=size),
        render=RenderSpec(mode=mode),
    )


def n_modules(n):
    """The Cube organisation at n modules (the family's parameter; 16 is the prototype)."""
    return dataclasses.replace(resolve_arch("cube1"), pipelines=n, max_volume=(n, n, n))


@pytest.fixture(scope="module")
def mr32(shared_data):
    mr = read_volume(shared_data / "mr_brainsmall.nrrd")  # 84 x 128 x 128
    return dataclasses.replace(mr, data=np.ascontiguousarray(mr.data[10:74:2, ::4, ::4]))


def rungs(scene, arch, volume=None, extend=False):
    return {f: render(scene, fidelity=f, arch=arch, volume=volume, extend=extend) for f in RUNGS}


def agree(runs):
    functional, transaction, cycle = (runs[f] for f in RUNGS)
    assert np.array_equal(cycle.image, functional.image)
    assert np.array_equal(transaction.image, functional.image)
    assert transaction.cycles == cycle.cycles > 0
    assert np.ptp(functional.image) > 0  # something was rendered


VIEWS = [((0, 0), "composite"), ((90, 0), "mip"), ((0, 90), "iso")]


@pytest.mark.parametrize(("view", "mode"), VIEWS)
def test_a_real_32_cube_on_32_modules_is_bit_identical(mr32, view, mode):
    scene = scene_of(view, mode, size=32)
    runs = rungs(scene, n_modules(32), mr32)
    agree(runs)
    c = runs["cycle"].counters
    assert c["memory.beam_reads"] == 32 * 32 and c["memory.conflict_cycles"] == 0


def test_a_real_32_cube_on_the_16_module_prototype_as_bricks(mr32):
    agree(rungs(scene_of(size=32), "cube1", mr32, extend=True))


def test_a_built_in_16_cube_beam_by_beam():
    runs = rungs(scene_of((180, 0)), "cube1")
    agree(runs)
    c = runs["cycle"].counters
    assert c["memory.access_cycles"] == 256 and c["memory.conflict_cycles"] == 0
    assert c["bus.levels"] == 4 and c["bus.select_cycles"] == 256 * 4
    assert runs["cycle"].cycles == 256 + 256 * 4 + c["pipeline.latency_cycles"]


def test_beams_longer_than_n_take_more_accesses():
    """A 32-deep buffer on 16 modules: every beam meets each module twice."""
    arch = dataclasses.replace(resolve_arch("cube1"), max_volume=(32, 32, 32))
    runs = rungs(scene_of(size=32), arch)
    agree(runs)
    c = runs["cycle"].counters
    assert c["memory.access_cycles"] == 2 * 32 * 32 and c["memory.conflict_cycles"] == 32 * 32


@pytest.mark.parametrize("fidelity", ("golden", *RUNGS))
def test_an_oblique_view_is_refused_at_every_rung(fidelity):
    refused = "view.azimuth: Cube-1 projects from predetermined directions"
    with pytest.raises(InputError, match=refused):
        render(scene_of((30, 15)), fidelity=fidelity, arch="cube1")


def test_a_stuck_module_shows_in_the_cycle_image():
    scene = scene_of()
    arch = resolve_arch("cube1")
    from hwsim.volumes import load_volume

    volume = load_volume(scene.volume, scene.base_dir)
    tf = resolve_transfer(scene.transfer, volume)
    frame = frame_of(scene, volume, tf, arch, make_plan(scene, volume, arch.order))
    good = render_functional(frame).image
    broken = Cube1Machine(Backend(frame), faults=Cube1Faults(stuck_module=3)).run()
    assert not np.array_equal(broken.image, good)
    assert np.array_equal(Cube1Machine(Backend(frame)).run().image, good)


def test_the_figure_and_the_independence_are_declared():
    arch = resolve_arch("cube1")
    (fig,) = published_figures(arch)
    assert (fig.key, fig.evidence, fig.value) == ("fps_16", "prediction", 30.0)
    comparison = transaction_vs_cycle(arch)
    assert comparison.verdict == "partly shared" and "bus_levels" in comparison.label
