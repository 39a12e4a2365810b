"""The ``transaction`` rung on VolumePro 500 and EM-Cube: SDRAM-fed slab machines.

The event model times the VolumePro-family rules of docs/cycle.md at beam-group
granularity over the shared SDRAM model (``SdramTransactionPort``).  The cycle rung
models the same machines, and the counts are compared against the 2 % contract; the
mechanism tests below also hold the model to the machine's rules.

Partly shared (``hwsim.studies.trade.independence``): the SDRAM controller, the mini-block
layout, ``pipeline_latency`` and ``slab_buffers`` are one copy for both rungs, so the
comparison measures the event model's own chunk schedule, sections and pixel bus, not
the SDRAM timing.  The 2 % on frame cycles does not see the SDRAM's timing at all (one
clock of ``t_rcd`` is 9 clocks of a 10 152-clock frame, docs/evidence.md), so the memory
timing has comparisons of its own (``tests/memory/memory_timing.py``, docs/transaction.md
"The memory timing, compared"): the SDRAM's counters equal (a consistency check of what
each rung hands the shared controller: bursts, arrival cycles, device parameters) and
the pipelines' memory stall, computed apart, equal at the event model's finest
granularity (one mini-block beam per chunk).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs
from memory_timing import (
    FINEST_GROUPS,
    STREAM,
    assert_memory_timing_agrees,
    memory_regime,
    memory_timing_checks,
    memory_timing_mismatches,
)

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.engine.fifo import DeadlockError
from hwsim.golden import make_plan
from hwsim.memory import parse_memory
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import TransferSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom, read_volume
from models.frame import frame_of
from models.machines.cube4.cycle import UNITS
from models.transaction import transaction_timing
from models.units import skew

pytestmark = pytest.mark.model

MACHINES = ["volumepro500", "em-cube"]


def scene_of(phantom="head", az=30, el=20, *, image=32, mode="composite", ss=1.0):
    return rungs.scene_of(
        az, el, phantom=phantom, size=image, mode=mode, render={"supersampling": ss}
    )


def timing(scene, volume, arch, **options):
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
    return transaction_timing(frame, **options), frame.plan


def cycle_run(scene, volume, arch):
    from models.cycle import render_cycle

    plan = make_plan(scene, volume, arch.order)
    tf = resolve_transfer(scene.transfer, volume)
    return render_cycle(frame_of(scene, volume, tf, arch, plan))


def cycle_count(scene, volume, arch) -> int:
    return cycle_run(scene, volume, arch).cycles


def assert_memory_timing_is_the_cycle_rungs(exact, scene, volume, arch, *, stall=True):
    """The memory comparisons of ``memory_timing``: the SDRAM's counters at the model's
    own granularity, and with the stall at its finest (``stall``: required compared)."""
    coarse = timing(scene, volume, arch)[0]
    assert_memory_timing_agrees(exact.counters, coarse.counters, stall=False)
    finest = timing(scene, volume, arch, groups=FINEST_GROUPS)[0]
    return assert_memory_timing_agrees(exact.counters, finest.counters, stall=stall)


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=32)


@pytest.mark.parametrize("arch", MACHINES)
def test_image_is_the_functional_image(head, arch):
    scene = scene_of()
    txn = render(scene, fidelity="transaction", arch=arch, volume=head)
    fixed = render(scene, fidelity="functional", arch=arch, volume=head)
    assert np.array_equal(txn.image, fixed.image) and txn.samples == fixed.samples
    assert txn.cycles > fixed.cycles  # memory fill, refresh, latency, bus drain


@pytest.mark.parametrize("arch", MACHINES)
def test_sdram_counters_follow_the_mini_block_layout(head, arch):
    machine = resolve_arch(arch)
    t, plan = timing(scene_of(), head, machine)
    c = t.counters
    n = head.shape[0]
    assert c["memory.bursts"] == (n // 2) ** 3  # every mini-block read once, one burst each
    assert c["memory.mbb_reads"] == (n // 2) ** 2
    assert c["memory.read_bytes"] == 2 * head.data.size
    assert (
        c["memory.sdram.row_hits"] + c["memory.sdram.row_misses"] + c["memory.sdram.row_conflicts"]
        == c["memory.bursts"]
    )
    memory = parse_memory(machine.memory, source="t")
    assert (
        c["memory.busy_cycles"] * memory.modules == c["memory.bursts"] * memory.sdram.burst_cycles
    )
    assert c["memory.stall_cycles"] > 0  # the first fill at least
    assert c["pixel_bus.pixels"] == plan.ray_ids.size


@pytest.mark.parametrize("arch", MACHINES)
def test_cycles_never_beat_the_pipelines_and_a_narrow_memory_is_the_bottleneck(head, arch):
    """Lower bound: every sample slice costs n_a C clocks.  Halving the modules halves
    the memory's bandwidth (2 words per clock against 4 voxels per clock consumed), so
    the frame becomes memory-bound: at least the bursts' data beats on 2 modules."""
    machine = resolve_arch(arch)
    scene = scene_of()
    t, plan = timing(scene, head, machine)
    n, P = head.shape[0], machine.pipelines
    C = -(-n // P)
    latency = skew.LATENCY + C + 1 + sum(u.LATENCY for u in UNITS.values())
    assert t.cycles >= plan.n_steps * n * C + latency
    narrow = dataclasses.replace(machine, memory={**machine.memory, "modules": 2})
    slow, _ = timing(scene, head, narrow)
    burst_cycles = parse_memory(narrow.memory, source="t").sdram.burst_cycles
    assert slow.cycles >= (n // 2) ** 3 * burst_cycles // 2
    assert slow.counters["memory.stall_cycles"] > t.counters["memory.stall_cycles"]


def test_supersampling_costs_pipeline_time_not_memory_traffic(head):
    arch = resolve_arch("volumepro500")
    once, plan1 = timing(scene_of(), head, arch)
    twice, plan2 = timing(scene_of(ss=2.0), head, arch)
    assert plan2.n_steps == 2 * plan1.n_steps - 1
    assert twice.counters["memory.bursts"] == once.counters["memory.bursts"]
    n, C = head.shape[0], -(-head.shape[0] // arch.pipelines)
    assert twice.cycles >= plan2.n_steps * n * C > once.cycles  # every sample slice: n_a C


def test_a_small_input_buffer_waits_and_one_too_small_deadlocks(head):
    arch = resolve_arch("volumepro500")
    n, C = head.shape[0], -(-head.shape[0] // 4)
    roomy, _ = timing(scene_of(), head, arch)
    tight_arch = dataclasses.replace(arch, buffers={"slab_buffer_entries": 4 * C * 3 * (n // 2)})
    tight, _ = timing(scene_of(), head, tight_arch)  # three slabs: the window and no more
    assert roomy.counters["memory.buffer_full_cycles"] == 0
    assert tight.counters["memory.buffer_full_cycles"] > 0 and tight.cycles >= roomy.cycles
    # One mini-block beam short of a slab: the slab's first voxel slice is read through
    # before its second frees any of its mini-block beams (rules 3', 5').
    tiny = dataclasses.replace(arch, buffers={"slab_buffer_entries": 4 * C * (n // 2 - 1)})
    with pytest.raises(DeadlockError, match="input buffer"):
        timing(scene_of(), head, tiny)


def test_the_slab_model_refuses_beam_skipping_rather_than_ignoring_it(head):
    """VolumePro 1000 goes to its own model (tests/models/test_transaction_vp1000.py);
    the plain slab model, asked directly, refuses a machine that skips beams."""
    from models.machines.volumepro.transaction import SlabTransaction

    scene, arch = scene_of(), resolve_arch("volumepro1000")
    frame = frame_of(scene, head, resolve_transfer(scene.transfer, head), arch)
    with pytest.raises(NotAvailableError, match="skips beams"):
        SlabTransaction(frame)


def sectioned(width, overhead=0):
    arch = resolve_arch("volumepro500")
    return dataclasses.replace(arch, section_width=width, section_overhead_cycles=overhead)


def test_sections_park_the_rays_that_cross_a_band_and_reread_the_overlap(head):
    whole, _ = timing(scene_of(az=30, el=20), head, resolve_arch("volumepro500"))
    oblique, plan = timing(scene_of(az=30, el=20), head, sectioned(8, 100))
    straight, _ = timing(scene_of(az=0, el=0), head, sectioned(8, 100))
    c = oblique.counters
    n = head.shape[0]
    assert c["section.count"] == -(-n // 8) and whole.counters["section.count"] == 1
    assert c["section.parked_rays"] > 0 and straight.counters["section.parked_rays"] == 0
    # Every band re-reads the mini-block beams of its rows a0 - 2 .. a1 + 1.
    assert c["memory.bursts"] > whole.counters["memory.bursts"] == (n // 2) ** 3
    bands = -(-n // 8)
    overheads = (bands - 1) * 100 + c["section.parked_rays"]  # reload one ray per clock
    assert c["section.overhead_cycles"] == overheads
    assert c["pixel_bus.pixels"] == plan.ray_ids.size + c["section.parked_rays"]
    assert oblique.cycles > whole.cycles


def test_sections_need_a_parallel_view():
    from models.machines.common.sections import bands_of

    volume = make_phantom("head", size=16)
    scene = scene_of(image=16)
    scene = scene.replace(view=dataclasses.replace(scene.view, projection="perspective"))
    plan = make_plan(scene, volume, "shear-image")
    with pytest.raises(InputError, match="overheads.section_width"):
        bands_of(plan, 4, 16, 1, "t.toml")


@pytest.mark.parametrize(("width", "overhead"), [(6, 50), (8, 0), (5, 10)])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20), (150, -30), (-60, 35)])
def test_sectioned_cycles_within_the_contract(width, overhead, az, el):
    """Sections compare the SDRAM's counters, not the stall: the bands are each rung's
    own (the cycle rung stretches a band's slices by its busiest lane, the model does
    not), which moves the pipelines against the memory (memory_timing)."""
    volume, arch = make_phantom("head", size=24), sectioned(width, overhead)
    scene = scene_of(az=az, el=el, image=24)
    exact = cycle_run(scene, volume, arch)
    approx = timing(scene, volume, arch)[0].cycles
    rungs.assert_within_contract(exact.cycles, approx)
    assert_memory_timing_is_the_cycle_rungs(exact, scene, volume, arch, stall=False)


@pytest.mark.parametrize("arch", MACHINES)
@pytest.mark.parametrize("phantom", ["head", "ball", "marschner-lobb"])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20), (150, -30), (90, 45)])
def test_cycles_within_the_contract_of_the_cycle_rung(arch, phantom, az, el):
    """Frame cycles within 2 %; the memory timing, which the 2 % cannot see, equal
    (memory_timing: the whole volume fits the input buffer, so both rungs queue every
    burst at cycle 0)."""
    machine = resolve_arch(arch)
    volume = make_phantom(phantom, size=32)
    scene = scene_of(phantom, az, el)
    exact = cycle_run(scene, volume, machine)
    approx = timing(scene, volume, machine)[0].cycles
    rungs.assert_within_contract(exact.cycles, approx)
    assert memory_regime(exact.counters) == "unthrottled"
    assert_memory_timing_is_the_cycle_rungs(exact, scene, volume, machine)


@pytest.mark.parametrize("ss", [2.0, 3.0])
def test_supersampled_cycles_within_the_contract(ss):
    machine, volume = resolve_arch("volumepro500"), make_phantom("head", size=24)
    scene = scene_of(image=24, ss=ss)
    exact = cycle_run(scene, volume, machine)
    approx = timing(scene, volume, machine)[0].cycles
    rungs.assert_within_contract(exact.cycles, approx)
    assert_memory_timing_is_the_cycle_rungs(exact, scene, volume, machine)


def three_slabs(arch, n=32):
    """``arch`` with an input buffer of three slabs of an ``n``-cube: the sample window
    and no more, so the reads wait for freed slots."""
    C = -(-n // arch.pipelines)
    return dataclasses.replace(
        arch, buffers={**arch.buffers, "slab_buffer_entries": 12 * C * n // 2}
    )


def fewer_modules(arch, modules):
    return dataclasses.replace(arch, memory={**arch.memory, "modules": modules})


#: Frames where the memory, not the pipelines, sets the pace (and the input buffer
#: throttles the reads): (machine, volume side, supersampling, regime).
MEMORY_BOUND = {
    "2 modules": (lambda: fewer_modules(resolve_arch("volumepro500"), 2), 32, 1.0, "unthrottled"),
    "em-cube, 1 module": (
        lambda: fewer_modules(resolve_arch("em-cube"), 1),
        32,
        1.0,
        "unthrottled",
    ),
    "2 modules, supersampling 2": (
        lambda: fewer_modules(resolve_arch("volumepro500"), 2),
        24,
        2.0,
        "unthrottled",
    ),
    "buffer of 3 slabs": (lambda: three_slabs(resolve_arch("volumepro500")), 32, 1.0, "backlogged"),
    "2 modules, buffer of 3 slabs": (
        lambda: three_slabs(fewer_modules(resolve_arch("volumepro500"), 2)),
        32,
        1.0,
        "backlogged",
    ),
    "96^3, larger than the buffer": (lambda: resolve_arch("volumepro500"), 96, 1.0, "backlogged"),
}


@pytest.mark.parametrize("case", list(MEMORY_BOUND))
def test_memory_timing_equals_the_cycle_rungs_where_the_memory_sets_the_pace(case):
    """Fewer modules (the memory is the bottleneck), a buffer that throttles the reads,
    a volume larger than the buffer: the SDRAM's counters equal, and the stall at the
    model's finest granularity (memory_timing)."""
    make, n, ss, regime = MEMORY_BOUND[case]
    machine, volume = make(), make_phantom("head", size=n)
    scene = scene_of(image=n, ss=ss)
    exact = cycle_run(scene, volume, machine)
    assert memory_regime(exact.counters) == regime
    assert_memory_timing_is_the_cycle_rungs(exact, scene, volume, machine)


def test_where_the_sdram_waits_for_freed_slots_only_the_stream_and_refreshes_are_compared(head):
    """Supersampling 2 with a three-slab buffer: the pipelines free slots slower than
    the memory reads, so the SDRAM waits for requests whose cycles each rung's buffer
    sets (the model frees a pair's mini-block beams one beam later): the bursts, data
    beats, first beats and refreshes (within one per module) are compared, the rest
    listed as not compared."""
    machine, scene = three_slabs(resolve_arch("volumepro500")), scene_of(ss=2.0)
    exact = cycle_run(scene, head, machine)
    assert memory_regime(exact.counters) == "waiting"
    finest = timing(scene, head, machine, groups=FINEST_GROUPS)[0]
    checks = memory_timing_checks(exact.counters, finest.counters)
    compared = {c.quantity for c in checks if c.compared}
    assert compared == {f"memory.sdram.{k}" for k in (*STREAM, "refreshes")}
    assert not memory_timing_mismatches(exact.counters, finest.counters)


def _sdram_ports_with(monkeypatch, **change):
    """The transaction rung's SDRAM ports built with ``change`` applied to the machine's
    parameters (``change[key](value)``); the arch both rungs read is untouched."""
    from models.machines.volumepro import pipeline_events as model

    class Port(model.SdramTransactionPort):
        def __init__(self, env, cfg):
            values = {k: f(getattr(cfg, k)) for k, f in change.items()}
            super().__init__(env, dataclasses.replace(cfg, **values))

    monkeypatch.setattr(model, "SdramTransactionPort", Port)


#: One SDRAM parameter of the transaction rung off, and the memory stall it adds on the
#: contract scene (head 32^3, view 30,20; docs/transaction.md).
SDRAM_CHANGES = {
    "t_rcd + 1": ({"t_rcd": lambda v: v + 1}, 9),
    "cas_latency + 1": ({"cas_latency": lambda v: v + 1}, 1),
    "t_refi / 2": ({"t_refi": lambda v: v // 2}, 117),
    "t_rfc x 2": ({"t_rfc": lambda v: 2 * v}, 72),
}


@pytest.mark.parametrize("name", list(SDRAM_CHANGES))
def test_the_memory_comparison_sees_the_transaction_rungs_sdram_off_by_a_clock(
    head, monkeypatch, name
):
    """The comparison can fail where the 2 % cannot: with one SDRAM parameter of the
    transaction rung's ports changed (its own input to the shared controller), the frame
    stays within 2 % but the SDRAM's counters and the stall (computed apart) differ."""
    machine, scene = resolve_arch("volumepro500"), scene_of()
    exact = cycle_run(scene, head, machine)
    change, stall = SDRAM_CHANGES[name]
    _sdram_ports_with(monkeypatch, **change)
    finest = timing(scene, head, machine, groups=FINEST_GROUPS)[0]
    rungs.assert_within_contract(exact.cycles, timing(scene, head, machine)[0].cycles)
    bad = {
        c.quantity: c.difference for c in memory_timing_mismatches(exact.counters, finest.counters)
    }
    assert bad.get("memory.stall_cycles") == stall, bad
    assert any(key.startswith("memory.sdram.") for key in bad), bad


def test_finer_groups_approach_the_cycle_count(head):
    """The error comes from granularity: one chunk per slab is further off than eight."""
    machine, scene = resolve_arch("volumepro500"), scene_of()
    exact = cycle_count(scene, head, machine)
    coarse = timing(scene, head, machine, groups=1)[0].cycles
    fine = timing(scene, head, machine, groups=8)[0].cycles
    assert abs(fine - exact) < abs(coarse - exact)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ct_cranium.nrrd", "mr_brainsmall.nrrd"])
def test_real_volumes_within_the_contract(shared_data, name):
    machine, volume = resolve_arch("volumepro500"), read_volume(shared_data / name)
    scene = scene_of(az=30, el=20, image=96).replace(transfer=TransferSpec(preset="auto"))
    exact = cycle_run(scene, volume, machine)
    approx = timing(scene, volume, machine)[0].cycles
    rungs.assert_within_contract(exact.cycles, approx)
    assert memory_regime(exact.counters) == "backlogged"  # larger than the input buffer
    assert_memory_timing_is_the_cycle_rungs(exact, scene, volume, machine)
