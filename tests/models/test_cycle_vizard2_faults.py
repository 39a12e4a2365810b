"""The VIZARD II cycle image comes from its modelled memory and cache: break one, the image
changes; the functional image, which has no such hardware, does not.

Also the ray queue: a queue that can hold no ray is a deadlock reported with its cause; a
pixel FIFO of depth 0 likewise; a shallow pixel FIFO costs cycles, not pixels.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
import rungs

from hwsim.engine import DeadlockError
from hwsim.run.fidelity import resolve_arch
from hwsim.volumes import make_phantom
from models.machines.vizard2.cycle import VizardFaults

pytestmark = pytest.mark.model


scene_of = functools.partial(rungs.fault_scene, size=24)


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=20)


def run(scene, volume, arch="vizard2", **kw):
    return rungs.functional_and_cycle(scene, volume, arch, **kw)[:2]


@pytest.fixture(scope="module")
def clean(head):
    return {mode: run(scene_of(mode), head) for mode in ("composite", "mip")}


@pytest.mark.parametrize(
    ("mode", "faults"),
    [
        ("mip", VizardFaults(stuck_word=(500, 30000))),
        ("composite", VizardFaults(stuck_bank=(0, 0))),
        ("composite", VizardFaults(corrupt_line=(5, 0x7FF))),
        ("mip", VizardFaults(dropped_fill=3)),
    ],
    ids=["stuck-word", "stuck-bank", "corrupt-cache-line", "dropped-fill"],
)
def test_each_broken_structure_changes_the_cycle_image_not_the_functional(
    head, clean, mode, faults
):
    scene = scene_of(mode)
    clean_f, clean_c = clean[mode]
    broken_f, broken_c = run(scene, head, faults=faults)
    assert np.array_equal(clean_c.image, clean_f.image)
    assert np.array_equal(broken_f.image, clean_f.image)  # functional has no such hardware
    assert not np.array_equal(broken_c.image, clean_c.image)
    # Data faults: the same lookups, fills and SDRAM commands.
    for key in ("cache.misses", "memory.bursts"):
        assert broken_c.counters[key] == clean_c.counters[key]


def test_a_stuck_word_reaches_only_rays_that_read_it(head, clean):
    """MIP with value word 500 stuck at a high value: pixels rise where rays read one of
    its 4 voxels, nowhere do they fall, and most pixels are untouched."""
    _, good = clean["mip"]
    _, bad = run(scene_of("mip"), head, faults=VizardFaults(stuck_word=(500, 30000)))
    changed = bad.image != good.image
    assert changed.any() and np.all(bad.image[changed] > good.image[changed])
    assert changed.mean() < 0.2


def test_an_empty_ray_queue_deadlocks_with_a_clear_report(head):
    with pytest.raises(DeadlockError, match=r"ray_queue: depth 0 .* rays pending at cycle 0"):
        run(scene_of(), head, faults=VizardFaults(ray_queue_entries=0))


def test_pixel_fifo_depth_zero_deadlocks_and_a_shallow_one_costs_cycles(head):
    with pytest.raises(DeadlockError, match="pixel_bus.fifo: depth 0"):
        run(scene_of(), head, faults=VizardFaults(pixel_fifo_depth=0))
    # One pixel leaves per clock.  With 256 rays queued, rays of similar length retire
    # in the same round: a depth-1 FIFO makes the issue wait for the bus.
    arch = resolve_arch("vizard2")
    arch = dataclasses.replace(arch, buffers={**arch.buffers, "ray_queue_entries": 256})
    f, roomy = run(scene_of("mip"), head, arch)
    _, tight = run(scene_of("mip"), head, arch, faults=VizardFaults(pixel_fifo_depth=1))
    assert np.array_equal(tight.image, roomy.image) and np.array_equal(roomy.image, f.image)
    assert tight.cycles > roomy.cycles
    assert (
        tight.counters["pipeline[0].interp.stall_cycles"]
        > (roomy.counters["pipeline[0].interp.stall_cycles"])
    )
