"""The cycle kernel: delay lines, the drain FIFO, ready/valid channels, stages, VCD."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.engine import Channel, Counters, DeadlockError, DelayLine, DrainFifo, Stage, VcdTrace
from hwsim.engine.metrics import derive

pytestmark = pytest.mark.model


@settings(max_examples=60, deadline=None)
@given(
    depth=st.integers(0, 9),
    blocks=st.lists(st.integers(1, 7), min_size=1, max_size=6),
    seed=st.integers(0, 2**16),
)
def test_delay_line_outputs_exactly_what_entered_depth_cycles_earlier(depth, blocks, seed):
    rng = np.random.default_rng(seed)
    total = sum(blocks)
    stream = rng.integers(1, 1000, size=(3, total))
    line = DelayLine(depth, 3)
    out = np.concatenate(
        [line.push(stream[:, sum(blocks[:i]) : sum(blocks[: i + 1])]) for i in range(len(blocks))],
        axis=1,
    )
    expected = np.zeros_like(stream)
    expected[:, depth:] = stream[:, : total - depth] if depth < total else expected[:, depth:]
    assert np.array_equal(out, expected)
    assert line.pushed == total and line.entries == 3 * depth


def test_delay_line_read_at_matches_push():
    rng = np.random.default_rng(1)
    block = rng.integers(0, 50, size=(4, 20))
    cycles = rng.integers(0, 20, size=(5, 6))
    lanes = rng.integers(0, 4, size=(5, 6))
    for depth in (0, 1, 3, 19):
        full = DelayLine(depth, 4).push(block)
        got = DelayLine.read_at(block, lanes * 20 + cycles, cycles, depth)
        assert np.array_equal(got, full[lanes, cycles])


def test_a_shallower_delay_line_delivers_the_next_entry():
    stream = np.arange(1, 11)[None, :]
    assert np.array_equal(DelayLine(3, 1).push(stream)[0, 3:], stream[0, :7])
    assert np.array_equal(DelayLine(2, 1).push(stream)[0, 3:], stream[0, 1:8])


def test_drain_fifo_counts_stalls_exactly():
    fifo = DrainFifo("bus", depth=4, rate=1)
    assert fifo.advance(cycles=10, arrivals=3, now=0) == 0
    # 3 queued; 2 cycles drain 2 -> 1 queued, 6 arrive: 3 fit, 3 wait one cycle each.
    assert fifo.advance(cycles=2, arrivals=6, now=10) == 3
    assert fifo.occupancy == 4 and fifo.max_occupancy == 4
    assert fifo.flush() == 4
    assert fifo.pushed == 9 == fifo.popped


def test_drain_fifo_without_room_is_a_reported_deadlock():
    fifo = DrainFifo("pixel_bus.fifo", depth=0)
    with pytest.raises(DeadlockError, match=r"pixel_bus.fifo: depth 0 .* 5 entries .* cycle 7"):
        fifo.advance(cycles=7, arrivals=5, now=0)


def test_channel_counts_transfers_stalls_and_idles_and_enforces_valid_hold():
    c = Counters()
    ch = Channel("pipeline[{}].interp.i", 1, c)
    valid = np.array([[1, 1, 1, 0, 1]], bool)
    ready = np.array([[0, 1, 1, 1, 1]], bool)
    fire = ch.observe(valid, ready)
    ch.publish()
    assert fire.tolist() == [[False, True, True, False, True]]
    assert c["pipeline[0].interp.i.transfers"] == 3
    assert c["pipeline[0].interp.i.stall_cycles"] == 1
    assert c["pipeline[0].interp.i.idle_cycles"] == 1
    with pytest.raises(ValueError, match="valid fell"):
        Channel("x[{}]", 1, Counters()).observe(np.array([[1, 0]], bool), np.array([[0, 0]], bool))


def test_stage_accounting_balances_and_refuses_impossible_blocks():
    c = Counters()
    s = Stage("interp", latency=4, ii=1, lanes=2, counters=c)
    s.account(np.array([5, 3]), cycles=8, stalled=2)
    s.publish()
    for lane in (0, 1):
        kinds = ("busy", "stall", "idle")
        assert sum(c[f"pipeline[{lane}].interp.{k}_cycles"] for k in kinds) == 8
    with pytest.raises(ValueError):
        s.account(np.array([9, 0]), cycles=8)
    with pytest.raises(ValueError):
        s.account(np.array([7, 0]), cycles=8, stalled=2)


def test_vcd_trace_nests_scopes_and_keeps_only_changes(tmp_path):
    tr = VcdTrace()
    tr.record("pipeline[1].interp", "o__valid", 1, [0, 1, 2, 3], [1, 1, 0, 0])
    tr.record("pipeline[1].interp", "o__payload", 8, [0, 2], [5, 300])
    text = tr.write(tmp_path / "t.vcd").read_text()
    assert "$scope module pipeline_1 $end" in text and "$scope module interp $end" in text
    assert "$var wire 8" in text and "$enddefinitions $end" in text
    assert text.count("#0") == 1 and "#1\n" not in text  # no change at cycle 1
    assert "b101100 " in text  # 300 masked to 8 bits = 44 = 0b101100
    with pytest.raises(ValueError, match="trace over"):
        VcdTrace(limit=2).record("a", "b", 1, [0, 1, 2], [0, 1, 0])


def test_derived_metrics_come_from_raw_counts():
    d = derive(
        {"pipeline[0].interp.busy_cycles": 50, "pipeline[0].interp.stall_cycles": 5},
        cycles=100,
        samples=150,
        pipelines=2,
        clock_hz=1e6,
    )
    assert d["samples_per_cycle"] == 1.5 and d["efficiency"] == 0.75
    assert d["frame_seconds"] == 1e-4
    assert d["units"]["pipeline[0].interp"] == {"utilisation": 0.5, "stall_share": 0.05}


def test_clock_counts_cycles_and_converts_to_seconds():
    from hwsim.engine import Clock

    clk = Clock(125e6)
    assert clk.advance(250) == 250 and clk.advance(0) == 250
    assert clk.seconds == 2e-6
    with pytest.raises(ValueError):
        clk.advance(-1)
    with pytest.raises(ValueError):
        Clock(0)


def test_stage_accounts_many_blocks_at_once_as_one_by_one():
    one, many = Counters(), Counters()
    a, b = Stage("x", 1, 1, 3, one), Stage("x", 1, 1, 3, many)
    busy = np.array([[4, 0, 2], [7, 7, 1]])
    cycles, stalled = np.array([6, 9]), np.array([1, 2])
    for k in range(2):
        a.account(busy[k], cycles[k], stalled[k])
    b.account(busy, cycles, stalled)
    a.publish()
    b.publish()
    assert one.as_dict() == many.as_dict()
    with pytest.raises(ValueError):
        b.account(np.array([[7, 0, 0]]), np.array([6]))
