"""VolumePro-family cycle images come from the modelled hardware: break a structure, see it.

Issue 5: fault-injection as for Cube-4.  A stuck SDRAM module or bank, a dropped ring
link or accumulator hand-off, a short beam FIFO, a lost section spill each change the
cycle image while the functional image, which has none of these structures, stays the
same; a short input buffer or pixel FIFO costs cycles, not pixels, and one too short for
the machine to progress is a DeadlockError naming the structure.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs

from hwsim.engine import DeadlockError
from hwsim.run.fidelity import resolve_arch
from hwsim.volumes import make_phantom
from models.machines.volumepro.cycle import SlabFaults as Faults

pytestmark = pytest.mark.model

ARCHS = ["volumepro500", "em-cube", "volumepro1000"]


scene_of = rungs.fault_scene


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=24)


def run(scene, volume, arch, **kw):
    return rungs.functional_and_cycle(scene, volume, arch, **kw)[:2]


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize(
    "faults",
    [
        Faults(stuck_module=(1, 4095)),
        Faults(stuck_bank=(2, 1, 4095)),
        Faults(dropped_link=2),
        Faults(dropped_handoff=0),
        Faults(beam_fifo_adjust=-1),
    ],
    ids=["stuck-module", "stuck-bank", "dropped-ring-link", "dropped-acc-handoff", "beam-fifo"],
)
def test_each_data_fault_changes_the_cycle_image_only(head, arch, faults):
    scene = scene_of()
    fixed, healthy = run(scene, head, arch)
    _, broken = run(scene, head, arch, faults=faults)
    assert np.array_equal(healthy.image, fixed.image)
    assert not np.array_equal(broken.image, fixed.image), "the fault did not reach the image"
    # The functional rung has no such structure: its image is the same as before.
    again, _ = run(scene, head, arch)
    assert np.array_equal(again.image, fixed.image)


@pytest.mark.parametrize("arch", ARCHS)
def test_a_lost_section_spill_loses_the_parked_partial_rays(head, arch):
    banded = dataclasses.replace(resolve_arch(arch), section_width=8)
    scene = scene_of()
    fixed, healthy = run(scene, head, banded)
    _, lost = run(scene, head, banded, faults=Faults(lost_spill=0))
    assert np.array_equal(healthy.image, fixed.image)
    assert healthy.counters["section.parked_rays"] > 0
    assert not np.array_equal(lost.image, fixed.image)
    # A spill at the last section parks nothing: harmless exactly there.
    _, last = run(scene, head, banded, faults=Faults(lost_spill=2))
    assert np.array_equal(last.image, fixed.image)


def test_a_short_input_buffer_costs_cycles_then_deadlocks(head):
    scene = scene_of("mip", lighting=False)
    arch = resolve_arch("volumepro500")
    _, roomy = run(scene, head, arch)
    C = -(-24 // 4)
    mbb = 4 * C  # entries per pipeline of one mini-block beam; 12 of them per slab
    # Rules 3', 5': the voxels stream through once, one slice ahead.  One slab: a mini-block
    # beam of the next slab issues only once its twin of this slab is freed by the second
    # slice's read of it, too late to hide the burst: the pipelines wait for it.
    small = dataclasses.replace(arch, buffers={"slab_buffer_entries": 12 * mbb})
    _, tight = run(scene, head, small)
    assert np.array_equal(tight.image, roomy.image)
    assert tight.cycles > roomy.cycles
    assert tight.counters["memory.buffer_full_cycles"] > roomy.counters["memory.buffer_full_cycles"]
    # One mini-block beam less: the slab's first slice is never read through.
    starved = dataclasses.replace(arch, buffers={"slab_buffer_entries": 11 * mbb})
    with pytest.raises(DeadlockError, match="input buffer"):
        run(scene, head, starved)
    with pytest.raises(DeadlockError, match="input buffer"):
        run(scene, head, arch, faults=Faults(slab_buffer_adjust=-(10**9)))


@pytest.mark.parametrize("arch", ARCHS)
def test_pixel_fifo_depth_zero_deadlocks_and_a_shallow_one_costs_cycles(head, arch):
    scene = scene_of("mip", lighting=False)
    with pytest.raises(DeadlockError, match="pixel_bus.fifo"):
        run(scene, head, arch, faults=Faults(pixel_fifo_depth=0))
    _, roomy = run(scene, head, arch)
    _, tight = run(scene, head, arch, faults=Faults(pixel_fifo_depth=4))
    assert np.array_equal(tight.image, roomy.image)
    assert tight.cycles > roomy.cycles
    assert tight.counters["pixel_bus.stall_cycles"] > 0
