"""Cycle-exact SDRAM timing, one rule at a time, against cycle numbers worked out by hand.

Default device (hwsim.memory.SdramConfig): tRCD 2, CL 2, tRP 2, tRAS 5, tRC 8, tRRD 2,
burst 8 (8 data cycles), queue depth 2; refresh off unless a test turns it on.  Each test's
docstring shows the arithmetic.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from sdram_checker import violations

from hwsim.memory import CONFLICT, HIT, MISS, SdramConfig, SdramController, schedule_bursts

pytestmark = pytest.mark.model

NO_REFRESH = SdramConfig(t_refi=0)


def run(cfg, bank, row, earliest=None, **kw):
    sched = schedule_bursts(cfg, bank, row, earliest, **kw)
    assert (
        violations(cfg, bank, row, earliest, sched, command_bus=kw.get("command_bus", True)) == []
    )
    return sched


def test_row_hits_stream_back_to_back():
    """ACT 0; READ at ACT + tRCD = 2, then every 8 cycles (data bus): 2, 10, 18.
    Beats from READ + CL: 4..11, 12..19, 20..27, so 28 cycles for 24 beats."""
    s = run(NO_REFRESH, [0, 0, 0], [1, 1, 1])
    assert s.activate.tolist() == [0, -1, -1]
    assert s.read.tolist() == [2, 10, 18]
    assert s.data_first.tolist() == [4, 12, 20]
    assert s.data_end.tolist() == [12, 20, 28]
    assert s.outcome.tolist() == [MISS, HIT, HIT]
    st = s.stats
    assert (st.row_hits, st.row_misses, st.row_conflicts) == (2, 1, 0)
    assert (st.elapsed_cycles, st.data_busy_cycles, st.first_access_cycles) == (28, 24, 4)
    assert st.efficiency == 24 / 28 and st.streaming_efficiency == 1.0


def test_cas_latency_3_delays_every_beat_by_one():
    s2 = run(NO_REFRESH, [0, 0, 0], [1, 1, 1])
    s3 = run(dataclasses.replace(NO_REFRESH, cas_latency=3), [0, 0, 0], [1, 1, 1])
    assert s3.read.tolist() == s2.read.tolist()
    assert s3.data_first.tolist() == [5, 13, 21]
    assert s3.cycles == s2.cycles + 1 == 29


def test_miss_on_another_bank_overlaps_and_respects_the_command_bus():
    """Bank 1's ACT wants cycle 2 (tRRD after ACT 0) but READ of bank 0 holds the command
    bus then, so ACT 3; its READ waits for the data bus: max(3 + 2, 2 + 8) = 10."""
    s = run(NO_REFRESH, [0, 1], [1, 1])
    assert s.activate.tolist() == [0, 3]
    assert s.read.tolist() == [2, 10]
    free = run(NO_REFRESH, [0, 1], [1, 1], command_bus=False)
    assert free.activate.tolist() == [0, 2] and free.read.tolist() == [2, 10]


def test_row_conflict_precharges_after_the_burst():
    """PRE >= max(ACT + tRAS, READ + burst) = max(5, 10) = 10; ACT 12; READ 14."""
    s = run(NO_REFRESH, [0, 0], [1, 2])
    assert s.precharge.tolist() == [-1, 10]
    assert s.activate.tolist() == [0, 12]
    assert s.read.tolist() == [2, 14]
    assert s.outcome.tolist() == [MISS, CONFLICT]
    assert s.cycles == 24 and s.stats.stall_bank_cycles == 4


def test_tras_and_trc_bind_with_short_bursts():
    """Burst 2: PRE >= max(ACT + tRAS, READ + 2) = max(5, 4) = 5 (tRAS);
    ACT >= max(PRE + tRP, ACT + tRC) = max(7, 8) = 8 (tRC); READ 10."""
    cfg = dataclasses.replace(NO_REFRESH, burst_length=2)
    s = run(cfg, [0, 0], [1, 2])
    assert s.precharge.tolist() == [-1, 5]
    assert s.activate.tolist() == [0, 8]
    assert s.read.tolist() == [2, 10]


def test_closed_page_auto_precharges():
    """Auto-precharge at max(READ + 8, ACT + tRAS) = 10; ready 12; the same row misses."""
    cfg = dataclasses.replace(NO_REFRESH, page_policy="closed")
    s = run(cfg, [0, 0], [1, 1])
    assert s.activate.tolist() == [0, 12]
    assert s.precharge.tolist() == [-1, -1]
    assert s.read.tolist() == [2, 14]
    assert s.outcome.tolist() == [MISS, MISS]


def test_bank_interleaving_hides_every_row_change():
    """Banks 0,1,2,3 then 0,1,2,3 on new rows.  Admission of request i is READ(i-2) + 1
    (queue depth 2): 0, 0, 3, 11, 19, 27, 35, 43.  ACTs 0, 3 (tRRD, bus), 5, 11; the
    conflicts precharge at admission (19, 27, 35, 43), activate tRP later; every READ
    still comes 8 cycles after the previous one: bursts are back-to-back."""
    s = run(NO_REFRESH, [0, 1, 2, 3, 0, 1, 2, 3], [0, 0, 0, 0, 1, 1, 1, 1])
    assert s.activate.tolist() == [0, 3, 5, 11, 21, 29, 37, 45]
    assert s.precharge.tolist() == [-1, -1, -1, -1, 19, 27, 35, 43]
    assert s.read.tolist() == [2, 10, 18, 26, 34, 42, 50, 58]
    assert s.stats.streaming_efficiency == 1.0 and s.stats.stall_bank_cycles == 0


def test_refresh_between_bursts():
    """tREFI 100, hits on one row: READ 2 + 8k.  Request 15 is admitted at READ(13) + 1 =
    107 >= 100, so the refresh comes first: PRECHARGE-ALL after the last burst in flight,
    max(100, READ(14) + 8) = 122; REFRESH 124; tRFC 9 -> 133; request 15 re-activates at
    133 and reads at 135: a 13-cycle gap (tRP + tRFC + tRCD)."""
    cfg = SdramConfig(t_refi=100)
    s = run(cfg, np.zeros(20, int), np.zeros(20, int))
    assert s.refresh.tolist() == [[122, 124]]
    assert s.read[14] == 114 and s.activate[15] == 133 and s.read[15] == 135
    st = s.stats
    assert st.refreshes == 1 and st.refresh_cycles == 11
    assert st.stall_refresh_cycles == 13 and st.stall_bank_cycles == 0
    assert st.elapsed_cycles == 135 + 4 * 8 + 2 + 8 == 177
    assert st.elapsed_cycles == (
        st.data_busy_cycles + st.first_access_cycles + st.stall_refresh_cycles
    )


def test_refreshes_fall_in_idle_time():
    """Second request arrives at 250: refresh 1 at its due cycle 100 (PREA 100, REF 102),
    refresh 2 at 200 (banks already closed: no PREA); then ACT 250, READ 252, and the gap
    is charged to the late arrival."""
    cfg = SdramConfig(t_refi=100)
    s = run(cfg, [0, 0], [0, 0], [0, 250])
    assert s.refresh.tolist() == [[100, 102], [-1, 200]]
    assert s.activate.tolist() == [0, 250] and s.read.tolist() == [2, 252]
    assert s.stats.stall_arrival_cycles == 242 and s.stats.stall_refresh_cycles == 0


def test_earliest_cycle_is_respected_and_admission_is_in_order():
    """Request 1 may not start before 40; request 2 (earliest 0) is admitted with it, at 40.
    Its ACT wants 42 (tRRD) where request 1's READ sits, so 43; READ max(45, 42 + 8)."""
    s = run(NO_REFRESH, [0, 1, 2], [0, 0, 0], [0, 40, 0])
    assert s.activate.tolist() == [0, 40, 43]
    assert s.read.tolist() == [2, 42, 50]


def test_ddr_burst_holds_the_bus_half_as_long():
    cfg = dataclasses.replace(NO_REFRESH, data_rate=2)
    s = run(cfg, [0, 0, 0], [1, 1, 1])
    assert cfg.burst_cycles == 4
    assert s.read.tolist() == [2, 6, 10]


def test_empty_stream():
    s = schedule_bursts(NO_REFRESH, [], [])
    assert s.cycles == 0 and s.stats.bursts == 0 and s.stats.efficiency == 0.0


@pytest.mark.parametrize(
    ("bank", "row", "earliest", "match"),
    [([4], [0], None, "bank"), ([0], [8192], None, "row"), ([0], [0], [-1], "earliest")],
)
def test_out_of_range_requests_are_refused(bank, row, earliest, match):
    with pytest.raises(ValueError, match=match):
        schedule_bursts(NO_REFRESH, bank, row, earliest)


def test_the_checker_catches_a_broken_schedule():
    """The independent checker is not vacuous: moving one READ a cycle early breaks tRCD."""
    bank, row = [0, 1], [1, 1]
    s = schedule_bursts(NO_REFRESH, bank, row)
    early = dataclasses.replace(s, read=s.read - np.array([1, 0]))
    assert any("tRCD" in v for v in violations(NO_REFRESH, bank, row, None, early))
    squeezed = dataclasses.replace(s, read=np.array([2, 9]))
    assert any("overlap" in v for v in violations(NO_REFRESH, bank, row, None, squeezed))


def test_fifo_backpressure_through_the_incremental_controller():
    """A consumer with a FIFO of 2 bursts that uses each burst for 12 cycles (slower than
    the memory's 8): burst i may not issue before burst i - 2 has been consumed.  The
    memory then waits on arrival: 12-cycle spacing, the gaps charged to arrival."""
    ctl = SdramController(NO_REFRESH)
    consumed: list[int] = []
    for i in range(10):
        earliest = consumed[i - 2] if i >= 2 else 0
        ctl.issue(i % 4, 0, earliest)
        start = max(ctl.data_end(i), consumed[-1] if consumed else 0)
        consumed.append(start + 12)
    s = ctl.schedule()
    assert np.all(np.diff(s.read[4:]) == 12)
    assert s.stats.stall_arrival_cycles > 0 and s.stats.stall_bank_cycles == 0
    with pytest.raises(ValueError, match="bank 9"):
        ctl.issue(9, 0)


def test_adopted_request_logs_give_the_schedule_of_fresh_ones():
    """Logs handed in by :meth:`SdramController.adopt_logs` (scratch another stream left
    full of its own cycles) are only written, never read before: the same schedule as a
    controller's own logs; refused once a request is in, or of the wrong shape."""
    rng = np.random.default_rng(5)
    cfg = SdramConfig(t_refi=60)
    bank, row = rng.integers(0, 4, 300), rng.integers(0, 3, 300)
    arrive = np.sort(rng.integers(0, 2000, 300))
    fresh = schedule_bursts(cfg, bank, row, arrive)
    ctl = SdramController(cfg)
    out, arrivals = np.full((4, 320), 7, dtype=np.int64), np.full(320, 9, dtype=np.int64)
    ctl.adopt_logs(out, arrivals)
    ctl.issue_many(bank, row, arrive)
    reused = ctl.schedule()
    for name in ("read", "activate", "precharge", "outcome", "refresh"):
        assert np.array_equal(getattr(reused, name), getattr(fresh, name)), name
    assert reused.stats == fresh.stats == ctl.stats()
    assert ctl.logs()[0] is out and np.array_equal(out[0, :300], fresh.read)
    with pytest.raises(RuntimeError, match="before the first request"):
        ctl.adopt_logs(out, arrivals)
    with pytest.raises(ValueError, match="columns"):
        SdramController(cfg).adopt_logs(out, arrivals[:10])
    with pytest.raises(ValueError, match="int64"):
        SdramController(cfg).adopt_logs(out.astype(np.int32), arrivals)
