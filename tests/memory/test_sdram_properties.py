"""Random streams on random devices: every timing rule holds, the counters add up, and the
SimPy form is the cycle form without the command-bus rule."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sdram_checker import violations

from hwsim.memory import SdramConfig, SdramController, schedule_bursts, simulate_events

pytestmark = pytest.mark.model


@st.composite
def devices(draw) -> SdramConfig:
    data_rate = draw(st.sampled_from([1, 2]))
    burst = draw(st.sampled_from([2, 4, 8] if data_rate == 2 else [1, 2, 4, 8]))
    t_ras = draw(st.integers(0, 6))
    t_rp = draw(st.integers(0, 4))
    t_rc = t_ras + t_rp + draw(st.integers(0, 3))
    t_rfc = draw(st.integers(0, 8))
    refresh = draw(st.booleans())
    floor = t_rfc + t_rp + t_rc + burst // data_rate
    return SdramConfig(
        banks=draw(st.integers(1, 4)),
        rows=4,
        columns=4 * burst,
        burst_length=burst,
        data_rate=data_rate,
        t_rcd=draw(st.integers(0, 4)),
        cas_latency=draw(st.integers(1, 3)),
        t_rp=t_rp,
        t_ras=t_ras,
        t_rc=t_rc,
        t_rrd=draw(st.integers(0, 3)),
        t_refi=draw(st.integers(floor + 1, floor + 80)) if refresh else 0,
        t_rfc=t_rfc,
        page_policy=draw(st.sampled_from(["open", "closed"])),
        queue_depth=draw(st.integers(1, 4)),
    )


@st.composite
def streams(draw):
    cfg = draw(devices())
    n = draw(st.integers(0, 40))
    bank = draw(st.lists(st.integers(0, cfg.banks - 1), min_size=n, max_size=n))
    row = draw(st.lists(st.integers(0, cfg.rows - 1), min_size=n, max_size=n))
    arrival = draw(st.sampled_from(["none", "sorted", "random"]))
    if arrival == "none":
        earliest = None
    else:
        earliest = draw(st.lists(st.integers(0, 300), min_size=n, max_size=n))
        if arrival == "sorted":
            earliest = sorted(earliest)
    return cfg, bank, row, earliest


@given(streams())
@settings(deadline=None, max_examples=300)
def test_every_timing_rule_holds(case):
    cfg, bank, row, earliest = case
    sched = schedule_bursts(cfg, bank, row, earliest)
    assert violations(cfg, bank, row, earliest, sched) == []


@given(streams())
@settings(deadline=None, max_examples=150)
def test_counters_add_up(case):
    cfg, bank, row, earliest = case
    s = schedule_bursts(cfg, bank, row, earliest).stats
    n = len(bank)
    assert s.bursts == n == s.row_hits + s.row_misses + s.row_conflicts
    assert s.data_busy_cycles == n * cfg.burst_cycles
    assert s.elapsed_cycles == (
        s.data_busy_cycles
        + s.first_access_cycles
        + s.stall_arrival_cycles
        + s.stall_bank_cycles
        + s.stall_refresh_cycles
    )
    assert s.idle_cycles == s.elapsed_cycles - s.data_busy_cycles >= 0
    assert 0.0 <= s.efficiency <= 1.0
    if cfg.page_policy == "closed":
        assert s.row_hits == 0 and s.row_conflicts == 0


@given(streams())
@settings(deadline=None, max_examples=100)
def test_simpy_form_equals_cycle_form_without_command_bus(case):
    """Same rules, different machinery: with the command-bus rule off (the one thing the
    burst-granularity event form leaves out) every command cycle and counter is equal."""
    cfg, bank, row, earliest = case
    cycle = schedule_bursts(cfg, bank, row, earliest, command_bus=False)
    events = simulate_events(cfg, bank, row, earliest)
    assert violations(cfg, bank, row, earliest, events, command_bus=False) == []
    for name in ("read", "activate", "precharge", "outcome", "refresh"):
        assert np.array_equal(getattr(cycle, name), getattr(events, name)), name
    assert cycle.stats == events.stats


@given(streams(), st.data())
@settings(deadline=None, max_examples=100)
def test_incremental_controller_equals_batch(case, data):
    """Issuing a stream one request or a few at a time gives the batch schedule."""
    cfg, bank, row, earliest = case
    batch = schedule_bursts(cfg, bank, row, earliest)
    ctl = SdramController(cfg)
    i, n = 0, len(bank)
    if data.draw(st.booleans()):  # room made up front changes no command
        ctl.reserve(data.draw(st.integers(0, n)))
    while i < n:
        k = data.draw(st.integers(1, 5))
        if k == 1:
            ctl.issue(bank[i], row[i], 0 if earliest is None else earliest[i])
        else:
            ctl.issue_many(
                bank[i : i + k], row[i : i + k], None if earliest is None else earliest[i : i + k]
            )
        i += k
    inc = ctl.schedule()
    for name in ("read", "activate", "precharge", "outcome", "refresh"):
        assert np.array_equal(getattr(batch, name), getattr(inc, name)), name
    assert batch.stats == inc.stats
    assert ctl.stats() == batch.stats  # counted straight from the logs: the same


@given(streams())
@settings(max_examples=100, deadline=None)
def test_compiled_loop_equals_its_python_source(case):
    """The controller's loop is numba-compiled; its Python source gives the same commands
    (no compiled-only integer or control-flow difference)."""
    from hwsim.memory.sdram_kernel import schedule_requests

    cfg, bank, row, earliest = case
    compiled = schedule_bursts(cfg, bank, row, earliest)
    ctl = SdramController(cfg)
    ctl._kernel = schedule_requests.py_func
    ctl.issue_many(bank, row, earliest)
    plain = ctl.schedule()
    for field in ("read", "activate", "precharge", "refresh"):
        assert np.array_equal(getattr(compiled, field), getattr(plain, field)), field


def test_long_idle_gaps_refresh_many_times_and_keep_every_rule():
    """Gaps of thousands of refresh intervals between requests (the refresh log and the
    command-bus book grow inside the compiled loop)."""
    cfg = SdramConfig(banks=4, rows=4, columns=32, t_refi=30, t_rfc=3)
    rng = np.random.default_rng(7)
    n = 200
    bank, row = rng.integers(0, 4, n), rng.integers(0, 4, n)
    earliest = np.cumsum(rng.integers(0, 400, n))
    sched = schedule_bursts(cfg, bank, row, earliest)
    assert violations(cfg, bank, row, earliest, sched) == []
    assert sched.stats.refreshes == pytest.approx(sched.cycles / cfg.t_refi, abs=2)
