"""The SDRAM command trace (hwsim/memory/sdram_trace.py): the controller's schedule as pin
commands, their VCD form and its reading back, the power-up sequence and mode register.
The replay through the checker is tests/cosim/test_sdram*.py."""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.engine import VcdTrace
from hwsim.memory import SdramConfig, schedule_bursts
from hwsim.memory.sdram_trace import (
    COMMANDS,
    command_trace,
    mode_register,
    powerup_trace,
    read_vcd_commands,
    record_commands,
    with_powerup,
)

pytestmark = pytest.mark.model


def _stream(cfg: SdramConfig, n: int = 400, seed: int = 5):
    rng = np.random.default_rng(seed)
    bank, row = rng.integers(0, cfg.banks, n), rng.integers(0, 3, n)
    earliest = np.sort(rng.integers(0, 6 * max(cfg.t_refi, 1), n))
    return bank, row, schedule_bursts(cfg, bank, row, earliest)


@pytest.mark.parametrize("policy", ["open", "closed"])
def test_every_scheduled_command_is_in_the_trace_once(policy):
    cfg = SdramConfig(page_policy=policy)
    bank, row, sched = _stream(cfg)
    trace = command_trace(cfg, sched, bank, row)
    assert np.all(np.diff(trace["cycle"]) > 0)  # one command a cycle, in time order
    count = {name: int(np.sum(trace["cmd"] == code)) for name, code in COMMANDS.items()}
    stats = sched.stats
    assert count["READ"] == stats.bursts
    assert count["ACT"] == stats.activates
    assert count["PRE"] == stats.precharges
    assert count["REF"] == stats.refreshes > 0
    reads = trace[trace["cmd"] == COMMANDS["READ"]]
    np.testing.assert_array_equal(reads["cycle"], sched.read)
    np.testing.assert_array_equal(reads["bank"], bank)
    assert np.all((reads["a"] == 1 << 10) == (policy == "closed"))  # auto precharge
    acts = trace[trace["cmd"] == COMMANDS["ACT"]]
    np.testing.assert_array_equal(acts["a"], row[sched.activate >= 0])


def test_a_schedule_without_the_command_bus_is_refused():
    cfg = SdramConfig()
    bank = np.array([0, 1, 2, 3] * 4)
    sched = schedule_bursts(cfg, bank, np.arange(16) % 3, command_bus=False)
    with pytest.raises(ValueError, match="share a cycle"):
        command_trace(cfg, sched, bank, np.arange(16) % 3)


def test_the_vcd_round_trip_keeps_equal_commands_on_consecutive_clocks(tmp_path):
    cfg = SdramConfig()
    bank, row, sched = _stream(cfg)
    trace = command_trace(cfg, sched, bank, row)
    twin = trace.copy()
    twin["cycle"] = np.arange(twin.size) * 1  # every command on the next clock
    vcd = VcdTrace()
    record_commands(vcd, "memory[0].sdram", trace)
    record_commands(vcd, "memory[3].sdram", twin)
    vcd.write(tmp_path / "w.vcd")
    back = read_vcd_commands(tmp_path / "w.vcd")
    assert sorted(back) == [0, 3]
    np.testing.assert_array_equal(back[0], trace)
    np.testing.assert_array_equal(back[3], twin)


def test_powerup_precedes_the_stream_with_the_mode_register():
    cfg = SdramConfig()
    assert mode_register(cfg) == 0x23  # CL 2, sequential, burst 8
    assert mode_register(SdramConfig(cas_latency=3, burst_length=4, columns=512)) == 0x32
    init, start = powerup_trace(cfg)
    names = {v: k for k, v in COMMANDS.items()}
    assert [names[c] for c in init["cmd"]] == ["PRE", "REF", "REF", "LMR"]
    assert init["a"][0] == 1 << 10  # PRECHARGE all
    assert init["cycle"][2] - init["cycle"][1] == cfg.t_rfc
    bank, row, sched = _stream(cfg, n=20)
    full = with_powerup(cfg, command_trace(cfg, sched, bank, row))
    assert full["cycle"][4] == start + command_trace(cfg, sched, bank, row)["cycle"][0]
    with pytest.raises(ValueError, match="bursts 1, 2, 4 or 8"):
        mode_register(SdramConfig(burst_length=16))
