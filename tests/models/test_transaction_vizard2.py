"""The ``transaction`` rung on VIZARD II: ray packets, block-cache misses as SDRAM bursts.

The model (``models/machines/vizard2/transaction.py``) resolves each packet's block lookups at once
against a tag-only direct-mapped cache and sends each miss group's fill to the shared
SDRAM transaction port; early ray termination comes from the functional rung's
termination steps, its speculative rounds estimated with stall-free rounds.  Without a
termination threshold it follows the machine's rules exactly (the same lookups, fills,
bursts and cycles as the cycle rung); with one, it stays within the 2 % contract.

These tests are the SimPy packet model's (``VizardTransaction.play``; the fixture below
keeps the rung from timing on its compiled packet model, the default, tested in
test_packet_timing_vizard2.py, or on the cycle rung's compiled ray loop,
:func:`test_the_loop_times_what_the_cycle_rung_times`, shared code, a consistency check).

Partly shared (``hwsim.studies.trade.independence``): both rungs call the cycle-exact
``SdramController``, ``BlockLayout.bursts``, ``FEEDBACK``/``FILL_WRITE``, the cache
geometry (``parse_buffers``), ``interp_taps`` and the leaping helpers; the packet
schedule, the tag-only cache (``_resolve``, the update rule of ``BlockCache.fetch``
written again) and the termination estimate are the model's own.  So the equal counts
below test those parts, not the SDRAM timing or the burst layout.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.engine import DeadlockError
from hwsim.golden import make_plan
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import read_volume
from models import cycle as cycle_module
from models.cycle import render_cycle
from models.frame import frame_of
from models.functional import render_functional
from models.machines.vizard2 import cycle as vizard2_module
from models.machines.vizard2.transaction import VizardTransaction
from models.transaction import timing_only, transaction_timing

pytestmark = pytest.mark.model

#: What the model resolves exactly as the machine does when no ray stops early (its own
#: packet schedule and tag-only cache; the bursts per fill come from the shared layout).
EXACT = ("cache.lookups", "cache.fills", "memory.bursts", "frame.issued_samples")


def scene_of(phantom="head", *, image=24, ert=1.0, **kw):
    return rungs.scene_of(
        30,
        15,
        phantom=phantom,
        size=image,
        preset="auto",
        zoom=1.0,
        render={"early_termination": ert},
        **kw,
    )


def machine(leaping=True, **buffers):
    arch = resolve_arch("vizard2")
    return dataclasses.replace(arch, space_leaping=leaping, buffers={**arch.buffers, **buffers})


def timing(scene, volume, arch, **options):
    tf = resolve_transfer(scene.transfer, volume)
    return transaction_timing(frame_of(scene, volume, tf, arch), **options)


@pytest.fixture(autouse=True)
def event_model(monkeypatch):
    """The transaction rung on its SimPy packet model, never on the compiled packet
    model or the cycle rung's loop."""
    monkeypatch.setattr(VizardTransaction, "run", VizardTransaction.play)


@pytest.fixture(scope="module")
def phantoms():
    return rungs.phantom_set(24, 24, 25)


@rungs.skipping_grid
def test_cycles_within_the_contract_of_the_cycle_rung(phantoms, phantom, projection, ert, leaping):
    volume = phantoms[phantom]
    exact, approx = rungs.within_contract(
        scene_of(phantom, ert=ert, projection=projection), volume, machine(leaping)
    )
    assert np.array_equal(approx.image, exact.image)  # functional = cycle image
    if ert == 1.0:  # nothing estimated: the machine's rules, exactly
        assert approx.cycles == exact.cycles
        rungs.assert_counters_equal(exact, approx, EXACT)


@pytest.mark.parametrize("mode", ["mip", "iso"])
def test_other_modes_within_the_contract(phantoms, mode):
    rungs.within_contract(scene_of(mode=mode), phantoms["head"], machine())


def test_a_smaller_cache_misses_more_and_each_fill_is_its_bursts(phantoms):
    volume, scene = phantoms["head"], scene_of(image=32)
    roomy = timing(scene, volume, machine())
    small = timing(scene, volume, machine(cache_sets=[2, 2, 2]))
    exact, _ = rungs.cycle_and_transaction(scene, volume, machine(cache_sets=[2, 2, 2]))
    assert small.counters["cache.fills"] > roomy.counters["cache.fills"] > 0
    assert small.cycles > roomy.cycles
    assert small.cycles == exact.cycles
    for t in (roomy, small):
        c = t.counters
        assert c["cache.hits"] + c["cache.misses"] == c["cache.lookups"]
        assert c["memory.bursts"] % c["cache.fills"] == 0  # whole lines, same burst count
        assert (
            c["memory.row_hits"] + c["memory.row_misses"] + c["memory.row_conflicts"]
            == (c["memory.bursts"])
        )


def test_termination_and_leaping_issue_fewer_samples(phantoms):
    volume = phantoms["head"]
    brute = timing(scene_of(), volume, machine(False))
    ert = timing(scene_of(ert=0.9), volume, machine(False))
    both = timing(scene_of(ert=0.9), volume, machine(True))
    issued = [t.counters["frame.issued_samples"] for t in (brute, ert, both)]
    assert issued[0] > issued[1] > issued[2]
    assert brute.cycles > ert.cycles > both.cycles
    assert ert.counters["ert.speculative_samples"] > 0 == brute.counters["ert.speculative_samples"]
    assert both.counters["frame.leaped_samples"] > 0 == ert.counters["frame.leaped_samples"]


def test_both_rungs_refuse_a_volume_the_memory_cannot_hold(phantoms):
    """One memory image and one capacity check (BlockLayout): a volume and gradient table
    over the SDRAM's pages is refused by the cycle and the transaction rung alike."""
    arch = machine()
    small = dataclasses.replace(arch, memory={**arch.memory, "rows": 1, "banks": 1})
    volume, scene = phantoms["head"], scene_of()
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), small)
    for rung in (render_cycle, transaction_timing):
        with pytest.raises(InputError, match="memory.rows"):
            rung(frame)


def test_the_event_model_never_runs_the_cycle_machine(phantoms, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the transaction rung ran the cycle machine")

    monkeypatch.setattr(vizard2_module.VizardMachine, "run", refuse)
    monkeypatch.setattr(cycle_module, "render_cycle", refuse)
    scene = scene_of(ert=0.95)
    run = render(scene, fidelity="transaction", arch="vizard2", volume=phantoms["head"])
    fixed = render(scene, fidelity="functional", arch="vizard2", volume=phantoms["head"])
    assert np.array_equal(run.image, fixed.image)
    assert run.cycles > 0 and run.counters["transaction.events"] > 0


def test_queue_and_fifo_depths(phantoms):
    volume, scene = phantoms["head"], scene_of(mode="mip")
    with pytest.raises(DeadlockError, match="ray_queue: depth 0"):
        timing(scene, volume, machine(ray_queue_entries=0))
    with pytest.raises(DeadlockError, match="pixel_bus.fifo: depth 0"):
        timing(scene, volume, machine(), pixel_fifo_depth=0)
    wide = machine(ray_queue_entries=256)
    roomy = timing(scene, volume, wide)
    tight = timing(scene, volume, wide, pixel_fifo_depth=1)
    assert tight.cycles > roomy.cycles and tight.counters["pixel_bus.max_occupancy"] == 1


def test_what_the_model_refuses(phantoms):
    volume, scene = phantoms["head"], scene_of()
    fast_memory = dataclasses.replace(machine(), memory={**machine().memory, "clock_ratio": 2.0})
    with pytest.raises(NotAvailableError, match="memory.clock_ratio"):
        timing(scene, volume, fast_memory)


def test_termination_steps_are_read_not_recomputed(phantoms):
    """Given the functional rung's termination steps, the model times the same frame
    as when it renders them itself."""
    volume, arch, scene = phantoms["head"], machine(), scene_of(ert=0.9)
    plan = make_plan(scene, volume, arch.order)
    tf = resolve_transfer(scene.transfer, volume)
    stopped = render_functional(frame_of(scene, volume, tf, arch, plan)).stopped
    given = transaction_timing(frame_of(scene, volume, tf, arch, plan), stopped=stopped)
    assert given.cycles == timing(scene, volume, arch).cycles


@pytest.mark.slow
@rungs.real_volume_grid
def test_real_volumes_within_the_contract(shared_data, name, ert, leaping, projection):
    volume = read_volume(shared_data / name)
    scene = scene_of(image=32, ert=ert, projection=projection)
    rungs.within_contract(scene, volume, machine(leaping))


@pytest.mark.parametrize("arch", ["vizard2", "volumepro1000"])
def test_hwsim_render_at_the_transaction_rung(tmp_path, arch):
    """The command line reaches both new models; cycles within the contract of the
    cycle rung's, the same image."""
    import json

    from hwsim.cli.commands import main

    args = ["render", "--phantom", "head:size=20", "--arch", arch, "--image", "20", "--quiet"]
    assert main([*args, "--fidelity", "transaction", "--out", str(tmp_path / "t")]) == 0
    assert main([*args, "--fidelity", "cycle", "--out", str(tmp_path / "c")]) == 0
    txn, cyc = (json.loads((tmp_path / d / "stats.json").read_text()) for d in ("t", "c"))
    assert txn["cycles"] == txn["counters"]["frame.cycles"]
    rungs.assert_within_contract(cyc["cycles"], txn["cycles"])
    images = [np.load(tmp_path / d / "image.npy") for d in ("t", "c")]
    assert np.array_equal(*images)


@pytest.mark.parametrize("phantom", ["head", "ball"])
@pytest.mark.parametrize("ert", [1.0, 0.9])
@pytest.mark.parametrize("leaping", [True, False])
@pytest.mark.parametrize("kind", [{}, {"mode": "mip", "projection": "perspective"}])
def test_the_loop_times_what_the_cycle_rung_times(
    phantoms, monkeypatch, phantom, ert, leaping, kind
):
    """Timing only on the cycle rung's compiled loop, datapath cut to the opacity that
    ends a ray (``RayKernel.timing``): the cycle rung's cycles and counters (shared
    code: this checks the cut, not the timing rules; the SimPy model above does)."""
    monkeypatch.undo()  # the rung's own choice: the loop
    volume, arch = phantoms[phantom], machine(leaping)
    scene = scene_of(phantom, ert=ert, **kind)
    tf = resolve_transfer(scene.transfer, volume)
    exact = render_cycle(frame_of(scene, volume, tf, arch))
    alone = transaction_timing(frame_of(scene, volume, tf, arch), shared_loop=True)
    assert alone.counters["transaction.granularity"] == "the cycle rung's ray loop, timing only"
    assert alone.cycles == exact.cycles
    keys = (*EXACT, "ert.speculative_samples", "memory.row_hits", "pixel_bus.max_occupancy")
    rungs.assert_counters_equal(exact, alone, keys)
    if ert < 1.0 and not kind:  # rays do end early, so the kept opacity decided clocks
        assert alone.counters["ert.speculative_samples"] > 0


def test_frames_out_of_the_loops_scope_take_the_packet_model(phantoms, monkeypatch):
    monkeypatch.undo()
    volume = phantoms["head"]
    scene = scene_of(projection="perspective")  # lit: a shader per ray, not the loop's
    tf = resolve_transfer(scene.transfer, volume)
    alone = timing_only(frame_of(scene, volume, tf, machine()))
    assert alone.counters["transaction.granularity"] == "packets, rounds and page runs (compiled)"
    assert transaction_timing(frame_of(scene, volume, tf, machine()), shared_loop=True).counters[
        "transaction.events"
    ]  # out of the loop's scope: the SimPy model played it
    forced = transaction_timing(frame_of(scene_of(), volume, tf, machine()), event_model=True)
    assert forced.counters["transaction.events"] > 0
