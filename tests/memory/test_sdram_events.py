"""The SimPy form against the cycle-exact form on the simple streams the brief names, and
as a component of a larger SimPy model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import simpy

from hwsim.memory import (
    SdramConfig,
    SdramEventModel,
    SdramTransactionPort,
    schedule_bursts,
    simulate_events,
)

pytestmark = pytest.mark.model

N = 3000
STREAMS = {
    "sequential": (np.zeros(N, int), np.arange(N) // 64),
    "bank-interleaved": (np.arange(N) % 4, np.arange(N) // 256),
    "row-thrashing": (np.zeros(N, int), np.arange(N) % 2),
    "bank-thrashing": (np.arange(N) % 2, (np.arange(N) // 2) % 2),
}


@pytest.mark.parametrize("policy", ["open", "closed"])
@pytest.mark.parametrize("refresh", [0, 976, 150])
@pytest.mark.parametrize("name", sorted(STREAMS))
def test_simple_streams_agree_cycle_for_cycle(name, refresh, policy):
    """With the command bus on (the cycle form's full rules) the completion times agree
    exactly on these streams: their commands never compete for a command-bus cycle."""
    cfg = SdramConfig(t_refi=refresh, page_policy=policy)
    bank, row = STREAMS[name]
    cycle = schedule_bursts(cfg, bank, row)
    events = simulate_events(cfg, bank, row)
    assert np.array_equal(cycle.data_end, events.data_end)
    assert np.array_equal(cycle.refresh, events.refresh)
    assert cycle.stats == events.stats


def test_paced_arrivals_agree():
    """Requests arriving every 10 cycles (a consumer slower than the memory)."""
    cfg = SdramConfig()
    bank, row = STREAMS["bank-interleaved"]
    earliest = np.arange(N) * 10
    cycle = schedule_bursts(cfg, bank, row, earliest)
    events = simulate_events(cfg, bank, row, earliest)
    assert np.array_equal(cycle.data_end, events.data_end)
    assert cycle.stats.stall_arrival_cycles > 0 and cycle.stats == events.stats


def test_where_the_forms_differ_it_is_the_command_bus():
    """A random stream: the event form has no command bus, so on this stream a few
    ACTIVATEs land earlier than in the cycle form and no burst ends later (not a general
    law: a command moved by a cycle can also move a refresh); switching the rule off in
    the cycle form removes every difference."""
    rng = np.random.default_rng(7)
    cfg = SdramConfig()
    bank, row = rng.integers(0, 4, N), rng.integers(0, 3, N)
    cycle = schedule_bursts(cfg, bank, row)
    events = simulate_events(cfg, bank, row)
    assert np.all(events.data_end <= cycle.data_end)
    assert not np.array_equal(cycle.activate, events.activate)
    free = schedule_bursts(cfg, bank, row, command_bus=False)
    assert np.array_equal(free.activate, events.activate)
    assert np.array_equal(free.data_end, events.data_end)


def test_model_embeds_in_a_caller_environment():
    """A consumer process requests bursts with a FIFO of two outstanding and waits on each
    ``done`` event; the times equal the cycle form fed the same arrival cycles."""
    cfg = dataclasses.replace(SdramConfig(), t_refi=0)
    env = simpy.Environment()
    model = SdramEventModel(env, cfg)
    done_at: list[int] = []
    requested_at: list[int] = []

    def consumer():
        pending = []
        for i in range(40):
            if len(pending) == 2:
                yield pending.pop(0).done
                yield env.timeout(5)  # the consumer works on the data
            requested_at.append(int(env.now))
            req = model.request(i % 4, i // 8)
            req.done.callbacks.append(lambda e: done_at.append(int(env.now)))
            pending.append(req)
        for req in pending:
            yield req.done

    env.process(consumer())
    env.run()
    cycle = schedule_bursts(cfg, np.arange(40) % 4, np.arange(40) // 8, requested_at)
    assert done_at == cycle.data_end.tolist()
    assert model.schedule().stats == cycle.stats


def test_bad_requests_are_refused():
    env = simpy.Environment()
    model = SdramEventModel(env, SdramConfig())
    with pytest.raises(ValueError, match="bank"):
        model.request(4, 0)
    with pytest.raises(ValueError, match="earliest"):
        simulate_events(SdramConfig(), [0], [0], [-3])


def test_transaction_port_times_a_beam_per_event():
    """A consumer reads beams of 16 bursts, spending 100 cycles on each beam: one event
    per beam, completion = the cycle form's last data beat for the same arrival cycles."""
    cfg = SdramConfig(t_refi=150)
    env = simpy.Environment()
    port = SdramTransactionPort(env, cfg)
    issued: list[int] = []
    finished: list[int] = []

    def consumer():
        for beam in range(6):
            issued.extend([int(env.now)] * 16)
            idx = np.arange(16)
            (first, last) = yield port.read(idx % 4, (beam * 16 + idx) // 64)
            assert (first, last) == (16 * beam, 16 * beam + 15)
            finished.append(int(env.now))
            yield env.timeout(100)

    env.process(consumer())
    env.run()
    idx = np.arange(96)
    cycle = schedule_bursts(cfg, idx % 4, idx // 64, issued)
    assert finished == cycle.data_end[15::16].tolist()
    assert port.schedule().stats == cycle.stats and cycle.stats.refreshes > 0
