"""The VolumePro family's compiled frame timing (models/machines/volumepro/timing_kernel.py)
plays out the same frame as the reference loop in slab_timing.run_timing, to the cycle.

Each case captures one cycle frame's timing inputs (the data pass's deliveries and slices)
and runs them both ways: the frame end, every slice's block, the stalls, every module's
command schedule (READ, ACTIVATE, PRECHARGE, refreshes) and its counters, each beam's end
and the pixel FIFO's state must all be equal; a buffer too small deadlocks both ways with
the same message.  Cases: the three machines, early termination and space leaping,
sections with parked rays, perspective, a tight input buffer, a shallow pixel FIFO.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs

from hwsim.core.threads import using
from hwsim.engine import Counters, DeadlockError, DrainFifo
from hwsim.volumes import make_phantom
from models.machines.volumepro import cycle as slab_cycle
from models.machines.volumepro import slab_timing, timing_kernel

pytestmark = pytest.mark.model


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=26)


def _inputs(monkeypatch, head, arch, scene):
    """The frame's ``run_timing`` arguments (captured from a cycle render on one thread:
    on two a slice-FIFO frame plays its timing beside the data pass, timing_ahead.py)."""
    seen = {}

    def spy(memory, table, slices, **kw):
        seen.update(memory=memory, table=table, slices=slices, kw=kw)
        # A shallow copy: the frame's own call drops its bursts once played (keep_bursts).
        return slab_timing.run_timing(memory, dataclasses.replace(table), slices, **kw)

    monkeypatch.setattr(slab_cycle, "run_timing", spy)
    with using(1):
        rungs.functional_and_cycle(scene, head, arch)
    return seen


def _play(seen, compiled, capacity=None, depth=None):
    kw = seen["kw"]
    fifo = DrainFifo("pixel_bus.fifo", kw["pixel_fifo"].depth if depth is None else depth)
    timing = slab_timing.run_timing(
        seen["memory"],
        seen["table"],
        seen["slices"],
        capacity=kw["capacity"] if capacity is None else capacity,
        pixel_fifo=fifo,
        counters=Counters(),
        keep_schedules=True,
        compiled=compiled,
    )
    return timing, fifo


def _assert_same(a, b):
    (ta, fa), (tb, fb) = a, b
    assert (ta.end, ta.blocks, ta.memory_stall, ta.pixel_stall) == (
        tb.end,
        tb.blocks,
        tb.memory_stall,
        tb.pixel_stall,
    )
    assert np.array_equal(ta.beam_ends, tb.beam_ends)
    assert ta.stats == tb.stats
    for x, y in zip(ta.schedules, tb.schedules, strict=True):
        for name in ("read", "activate", "precharge", "outcome", "refresh"):
            assert np.array_equal(getattr(x, name), getattr(y, name)), name
    assert vars(fa) == vars(fb)


CASES = {
    "vp500": ("volumepro500", rungs.scene_of(30, 20, size=26), {}),
    "em-cube": ("em-cube", rungs.scene_of(-70, 35, size=26), {}),
    "vp1000-ert-leaping": (
        "volumepro1000",
        rungs.scene_of(200, -30, size=26, render={"early_termination": 0.8}),
        {},
    ),
    "vp1000-perspective": ("volumepro1000", rungs.scene_of(40, 10, projection="perspective"), {}),
    "vp500-sections": ("volumepro500", rungs.scene_of(25, 15, size=26), {"section_width": 8}),
}


@pytest.mark.parametrize("case", CASES)
def test_compiled_timing_is_the_reference_loop(monkeypatch, head, case):
    name, scene, changes = CASES[case]
    seen = _inputs(monkeypatch, head, rungs.machine(name, **changes), scene)
    assert len(seen["table"]) > 0 and seen["kw"]["compiled"]
    reference = _play(seen, False)
    assert reference[0].stats[0].bursts > 0
    _assert_same(_play(seen, True), reference)
    # A tight input buffer (pipelines wait for reads) and a shallow pixel FIFO.
    capacity = seen["kw"]["capacity"]
    tight = max(capacity // 2, 1)
    try:
        expected = _play(seen, False, capacity=tight, depth=3)
    except DeadlockError as err:
        with pytest.raises(DeadlockError, match=str(err).split(";")[0]):
            _play(seen, True, capacity=tight, depth=3)
    else:
        _assert_same(_play(seen, True, capacity=tight, depth=3), expected)


def test_a_frame_whose_logs_outgrow_their_room_starts_again_alike(monkeypatch, head):
    """The compiled loop never grows its command-bus and refresh logs: a frame needing
    more room than sized starts again with twice as much, from fresh controllers and the
    pixel FIFO's first state; here from room for 2 commands and 1 refresh."""
    seen = _inputs(monkeypatch, head, rungs.machine("volumepro500"), rungs.scene_of(size=26))
    reference = _play(seen, False)
    assert reference[0].stats[0].refreshes > 1
    attempts = []
    one_attempt = timing_kernel._play

    def counted(*args):
        attempts.append(one_attempt(*args))
        return attempts[-1]

    monkeypatch.setattr(timing_kernel, "first_room", lambda *args: (2, 1))
    monkeypatch.setattr(timing_kernel, "_play", counted)
    _assert_same(_play(seen, True), reference)
    assert attempts[0] is False and attempts[-1] is True and len(attempts) >= 3


def test_a_starved_buffer_deadlocks_both_ways_alike(monkeypatch, head):
    seen = _inputs(monkeypatch, head, rungs.machine("volumepro500"), rungs.scene_of(size=26))
    messages = []
    for compiled in (False, True):
        with pytest.raises(DeadlockError, match="input buffer") as err:
            _play(seen, compiled, capacity=3)
        messages.append(str(err.value))
    assert messages[0] == messages[1]


def test_the_delivery_table_read_twice_keeps_each_module_contiguous(monkeypatch, head):
    seen = _inputs(monkeypatch, head, rungs.machine("em-cube"), rungs.scene_of(size=26))
    table = seen["table"]
    again = table.twice(1000)
    assert len(again) == 2 * len(table)
    one, two = table.as_list(), again.as_list()
    for g, d in enumerate(one):
        for k, (banks, rows) in enumerate(d.bursts):
            for copy in (two[g], two[g + len(one)]):
                assert np.array_equal(copy.bursts[k][0], banks)
                assert np.array_equal(copy.bursts[k][1], rows)
        assert two[g + len(one)].free_after == d.free_after + 1000
    assert dataclasses.astuple(one[0])[1] == table.free_after[0]
