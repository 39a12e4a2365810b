"""Simulator tier of the SDRAM device model and its datasheet checker (rtl/sdram).

The checker (``sdram_checker.v``, written from the MT48LC16M16A2 datasheet) catches each
rule with a hand-written trace that breaks it, and passes the same trace made legal; a
legal stream of the cycle-exact controller passes with the controller's own counts; the
device (``sdr_sdram.v``) returns the loaded words with the CAS latency and the burst order
of the mode register.  Each case runs on Icarus and Verilator (one build per simulator
and parameter set, under ``build/rtl/sdram_*``).  The cycle rung's own trace is replayed
in test_sdram_cycle_rung.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from simulators import require

from hwsim.memory import SdramConfig, schedule_bursts
from hwsim.memory.sdram_trace import (
    COMMANDS,
    TRACE_DTYPE,
    command_trace,
    mode_register,
    powerup_trace,
    with_powerup,
)
from rtl.sdram.sim import replay

pytestmark = pytest.mark.cosim
SIMULATORS = ["verilator", "icarus"]
CFG = SdramConfig()  # volumepro500's device: CL2 BL8, tRCD 2, tRP 2, tRAS 5, tRC 8, ...
AP = 1 << 10


def trace_of(*commands) -> np.ndarray:
    """``(cycle, command, bank, a)`` tuples as trace records."""
    out = np.zeros(len(commands), dtype=TRACE_DTYPE)
    for i, (cycle, cmd, bank, a) in enumerate(commands):
        out[i] = (cycle, COMMANDS[cmd], bank, a)
    return out


def refreshes_every(period: int, count: int, start: int = 0) -> list[tuple]:
    return [(start + k * period, "REF", 0, 0) for k in range(count)]


#: rule -> (commands breaking it, the same made legal).  Cycles count from the end of the
#: power-up sequence, except for the power-up and mode cases (the whole trace).
CASES = {
    "tRCD": ([(0, "ACT", 0, 3), (1, "READ", 0, 0)], [(0, "ACT", 0, 3), (2, "READ", 0, 0)]),
    "tRP": (
        [(0, "ACT", 0, 3), (7, "PRE", 0, 0), (8, "ACT", 0, 4)],
        [(0, "ACT", 0, 3), (6, "PRE", 0, 0), (8, "ACT", 0, 4)],
    ),
    "tRAS": ([(0, "ACT", 0, 3), (4, "PRE", 0, 0)], [(0, "ACT", 0, 3), (5, "PRE", 0, 0)]),
    "tRC": (
        [(0, "ACT", 0, 3), (5, "PRE", 0, 0), (7, "ACT", 0, 4)],
        [(0, "ACT", 0, 3), (5, "PRE", 0, 0), (8, "ACT", 0, 4)],
    ),
    "tRRD": ([(0, "ACT", 0, 3), (1, "ACT", 1, 3)], [(0, "ACT", 0, 3), (2, "ACT", 1, 3)]),
    "tWR": (
        [(0, "ACT", 0, 3), (2, "WRITE", 0, 0), (10, "PRE", 0, 0)],
        [(0, "ACT", 0, 3), (2, "WRITE", 0, 0), (11, "PRE", 0, 0)],
    ),
    "tRFC": ([(0, "REF", 0, 0), (8, "ACT", 0, 3)], [(0, "REF", 0, 0), (9, "ACT", 0, 3)]),
    "tREFI": (  # nine refreshes owed at 9 tREFI: one more than JEDEC's eight postponed
        [(0, "ACT", 0, 3), (5, "PRE", 0, 0), (9 * 976 + 1, "ACT", 0, 3)],
        [(0, "ACT", 0, 3), (5, "PRE", 0, 0), (8 * 976 + 1, "ACT", 0, 3)],
    ),
    "tRAS max": (
        [(0, "ACT", 0, 3), (15002, "PRE", 0, 0)],
        [(0, "ACT", 0, 3), (7000, "PRE", 0, 0)],
    ),
    "closed": ([(0, "READ", 0, 0)], [(0, "ACT", 0, 0), (2, "READ", 0, 0)]),
    "open": (
        [(0, "ACT", 0, 3), (8, "ACT", 0, 4)],
        [(0, "ACT", 0, 3), (6, "PRE", 0, 0), (8, "ACT", 0, 4)],
    ),
    "refresh": (
        [(0, "ACT", 0, 3), (10, "REF", 0, 0)],
        [(0, "ACT", 0, 3), (8, "PRE", 0, AP), (10, "REF", 0, 0)],
    ),
    "burst": (  # a PRECHARGE or a READ inside a burst cuts it short
        [(0, "ACT", 0, 3), (2, "READ", 0, 0), (6, "PRE", 0, 0)],
        [(0, "ACT", 0, 3), (2, "READ", 0, 0), (10, "PRE", 0, 0)],
    ),
    "burst-read": (
        [(0, "ACT", 0, 3), (2, "READ", 0, 0), (9, "READ", 0, 8)],
        [(0, "ACT", 0, 3), (2, "READ", 0, 0), (10, "READ", 0, 8)],
    ),
    "bus": (  # a WRITE while read data is on the bus
        [(0, "ACT", 0, 3), (2, "READ", 0, 0), (11, "WRITE", 0, 8)],
        [(0, "ACT", 0, 3), (2, "READ", 0, 0), (12, "WRITE", 0, 8)],
    ),
    "auto-precharge": (  # READ with auto precharge closes the bank: tRP from READ + BL
        [(0, "ACT", 0, 3), (2, "READ", 0, AP), (11, "ACT", 0, 4)],
        [(0, "ACT", 0, 3), (2, "READ", 0, AP), (12, "ACT", 0, 4)],
    ),
}
#: The rule name each case's violation line carries.
RULE = {"burst-read": "burst", "auto-precharge": "tRP"}


def _with_init(commands) -> np.ndarray:
    return with_powerup(CFG, trace_of(*commands))


def _powerup_cases() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    init, start = powerup_trace(CFG)
    act = trace_of((start, "ACT", 0, 3))
    no_lmr = init[:-1]  # PRECHARGE all, two refreshes, no LOAD MODE
    bad_mode = init.copy()
    bad_mode["a"][-1] = mode_register(SdramConfig(cas_latency=3))
    early = act.copy()
    early["cycle"] = init["cycle"][-1] + 1  # tMRD after LOAD MODE
    legal = np.concatenate([init, act])
    return {
        "power-up": (np.concatenate([no_lmr, act]), legal),
        "mode": (np.concatenate([bad_mode, act]), legal),
        "tMRD": (np.concatenate([init, early]), legal),
    }


ALL = [*CASES, *_powerup_cases()]


@pytest.mark.parametrize("sim", SIMULATORS)
@pytest.mark.parametrize("rule", ALL)
def test_the_checker_catches_each_rule(rule, sim):
    require(sim)
    if rule in CASES:
        bad, good = (_with_init(c) for c in CASES[rule])
    else:
        bad, good = _powerup_cases()[rule]
    broken = replay(bad, CFG, sim)
    name = RULE.get(rule, rule)
    assert broken.counts["violations"] >= 1
    assert any(f"VIOLATION {name} " in line for line in broken.violations), broken.violations
    legal = replay(good, CFG, sim)
    assert legal.counts["violations"] == 0, legal.violations


@pytest.mark.parametrize("sim", SIMULATORS)
def test_strict_fails_the_run(sim):
    require(sim)
    with pytest.raises(RuntimeError, match="without counts"):
        replay(_with_init(CASES["tRCD"][0]), CFG, sim, STRICT=1)


@pytest.mark.parametrize("sim", SIMULATORS)
@pytest.mark.parametrize("policy", ["open", "closed"])
def test_a_controller_stream_passes_with_its_counts(policy, sim):
    """Random requests (four banks, four rows, arrivals spread over 40 refresh intervals)
    scheduled by the cycle-exact controller: legal, and the checker counts what the
    controller's own counters say."""
    require(sim)
    cfg = SdramConfig(page_policy=policy)
    rng = np.random.default_rng(7)
    n = 3000
    bank, row = rng.integers(0, 4, n), rng.integers(0, 4, n)
    earliest = np.sort(rng.integers(0, 40 * cfg.t_refi, n))
    schedule = schedule_bursts(cfg, bank, row, earliest)
    got = replay(with_powerup(cfg, command_trace(cfg, schedule, bank, row)), cfg, sim)
    stats = schedule.stats
    assert got.counts["violations"] == 0, got.violations[:5]
    assert stats.refreshes > 30
    assert got.counts["activates"] == stats.activates
    assert got.counts["reads"] == stats.bursts == n
    assert got.counts["precharges"] == stats.precharges
    assert got.counts["refreshes"] == stats.refreshes
    assert got.counts["auto_precharges"] == (n if policy == "closed" else 0)


@pytest.mark.parametrize("sim", SIMULATORS)
def test_the_device_returns_the_loaded_words_after_cas_latency_in_burst_order(sim):
    require(sim)
    rows, cols = 256, 512  # sdram_tb's device: 4 banks x 256 rows x 512 columns
    rng = np.random.default_rng(3)
    memory = rng.integers(0, 1 << 16, 4 * rows * cols)
    init, start = powerup_trace(CFG)
    reads = [(2, 5, 13), (3, 7, 8)]  # (bank, row, column): column 13 wraps inside 8..15
    commands = [(start, "ACT", 2, 5), (start + 2, "ACT", 3, 7)]
    commands += [(start + 4, "READ", 2, 13), (start + 12, "READ", 3, 8)]
    got = replay(np.concatenate([init, trace_of(*commands)]), CFG, sim, memory=memory, dump=True)
    assert got.counts["violations"] == 0, got.violations
    edges, words = got.beats[:, 0], got.beats[:, 1]
    read_at = [start + 4, start + 12]
    expect_edges = np.concatenate([t + CFG.cas_latency + np.arange(8) for t in read_at])
    np.testing.assert_array_equal(edges, expect_edges)
    expect = []
    for bank, row, col in reads:
        block = col & ~7
        for i in range(8):
            expect.append(memory[(bank * rows + row) * cols + block + ((col + i) & 7)])
    np.testing.assert_array_equal(words, expect)
