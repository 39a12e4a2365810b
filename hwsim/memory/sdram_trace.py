"""The cycle-exact SDRAM controller's command stream, as the pins of one device would carry it.

# Ref: Micron 256Mb SDR SDRAM (MT48LC16M16A2) datasheet: command truth table (CS#, RAS#,
#      CAS#, WE#), initialization (PRECHARGE all, two AUTO REFRESH, LOAD MODE REGISTER),
#      mode register layout; rtl/sdram (the checker this stream is replayed through).

:func:`command_trace` turns a :class:`~hwsim.memory.BurstSchedule` (the command cycles
the controller chose) into one record per command, sorted by cycle: ``cycle`` (memory
clock), ``cmd`` (the pin code ``{cs_n, ras_n, cas_n, we_n}`` of :data:`COMMANDS`),
``bank`` and ``a`` (the address pins: the row on ACTIVATE; on READ the column, with bit 10
set for auto precharge under the closed page policy; bit 10 set on a PRECHARGE of all
banks).  The schedule holds rows, not columns (the column does not change the timing), so
a READ's column is 0.  :func:`powerup_trace` is the initialization the device needs
before the first ACTIVATE; :func:`with_powerup` puts it before a stream.
:func:`record_commands` puts a trace into a VCD waveform (the cycle rung's ``--trace``
does, per module) and :func:`read_vcd_commands` reads it back.  Nothing here runs unless a
caller asks for a trace.
"""

from __future__ import annotations

import numpy as np

from hwsim.memory.sdram import SdramConfig
from hwsim.memory.sdram_cycle import BurstSchedule

__all__ = [
    "COMMANDS",
    "TRACE_DTYPE",
    "T_MRD",
    "command_trace",
    "mode_register",
    "powerup_trace",
    "read_vcd_commands",
    "record_commands",
    "with_powerup",
]

#: Pin codes ``{cs_n, ras_n, cas_n, we_n}`` of the SDR SDRAM commands.
COMMANDS = {
    "LMR": 0b0000,
    "REF": 0b0001,
    "PRE": 0b0010,
    "ACT": 0b0011,
    "WRITE": 0b0100,
    "READ": 0b0101,
    "NOP": 0b0111,
}
#: One command: memory-clock cycle, pin code, bank, address pins.
TRACE_DTYPE = np.dtype([("cycle", "<i8"), ("cmd", "u1"), ("bank", "u1"), ("a", "<u2")])
#: LOAD MODE REGISTER to the next command, clocks [R: 2 tCK in Micron's MT48LC16M16A2
#: model parameters; the datasheet states it in clocks].
T_MRD = 2
_AP = 1 << 10  # a[10]: auto precharge (READ/WRITE), all banks (PRECHARGE)


def mode_register(cfg: SdramConfig) -> int:
    """The LOAD MODE value for ``cfg``: burst length, sequential bursts, CAS latency."""
    codes = {1: 0, 2: 1, 4: 2, 8: 3}
    if cfg.burst_length not in codes:
        raise ValueError(f"burst_length {cfg.burst_length}: an SDR SDRAM bursts 1, 2, 4 or 8")
    return (cfg.cas_latency << 4) | codes[cfg.burst_length]


def _records(cycle, cmd, bank, a) -> np.ndarray:
    out = np.zeros(np.asarray(cycle).size, dtype=TRACE_DTYPE)
    out["cycle"], out["cmd"], out["bank"], out["a"] = cycle, cmd, bank, a
    return out


def command_trace(cfg: SdramConfig, schedule: BurstSchedule, bank, row) -> np.ndarray:
    """Every command of ``schedule`` (the requests ``bank``, ``row`` in issue order) as
    :data:`TRACE_DTYPE` records sorted by cycle.

    Raises
    ------
    ValueError
        When two commands share a cycle (the schedule was made without the command bus).
    """
    bank = np.asarray(bank, dtype=np.int64).reshape(-1)
    row = np.asarray(row, dtype=np.int64).reshape(-1)
    read_a = _AP if cfg.page_policy == "closed" else 0
    act, pre = schedule.activate >= 0, schedule.precharge >= 0
    prea, ref = schedule.refresh[:, 0], schedule.refresh[:, 1]
    parts = [
        _records(schedule.read, COMMANDS["READ"], bank, read_a),
        _records(schedule.activate[act], COMMANDS["ACT"], bank[act], row[act]),
        _records(schedule.precharge[pre], COMMANDS["PRE"], bank[pre], 0),
        _records(prea[prea >= 0], COMMANDS["PRE"], 0, _AP),
        _records(ref, COMMANDS["REF"], 0, 0),
    ]
    trace = np.concatenate(parts)
    trace = trace[np.argsort(trace["cycle"], kind="stable")]
    if trace.size > 1 and np.any(np.diff(trace["cycle"]) == 0):
        raise ValueError("two commands share a cycle: schedule with the command bus")
    return trace


def powerup_trace(cfg: SdramConfig) -> tuple[np.ndarray, int]:
    """The initialization (PRECHARGE all; AUTO REFRESH twice, tRFC apart; LOAD MODE) from
    cycle 0, and the first cycle a stream may use after it (tMRD after LOAD MODE)."""
    ref1 = cfg.t_rp
    ref2 = ref1 + cfg.t_rfc
    lmr = ref2 + cfg.t_rfc
    trace = _records(
        [0, ref1, ref2, lmr],
        [COMMANDS["PRE"], COMMANDS["REF"], COMMANDS["REF"], COMMANDS["LMR"]],
        0,
        [_AP, 0, 0, mode_register(cfg)],
    )
    return trace, lmr + T_MRD


def with_powerup(cfg: SdramConfig, trace: np.ndarray) -> np.ndarray:
    """``trace`` shifted to start after :func:`powerup_trace`, the initialization first."""
    init, start = powerup_trace(cfg)
    shifted = trace.copy()
    shifted["cycle"] += start
    return np.concatenate([init, shifted])


#: The VCD signals of one module's command bus (scope ``memory[k].sdram``).
_VCD_SIGNALS = (("cmd", 4), ("ba", 2), ("a", 13), ("commands", 32))


def record_commands(vcd, scope: str, trace: np.ndarray) -> None:
    """Put ``trace`` into a :class:`hwsim.engine.VcdTrace` under ``scope``: the pins
    ``cmd`` (``{cs_n, ras_n, cas_n, we_n}``, NOP between commands), ``ba``, ``a``, and
    ``commands`` (how many commands so far: it changes on every command, so two equal
    commands on consecutive clocks stay two)."""
    t = trace["cycle"]
    idle = t + 1
    idle = idle[~np.isin(idle, t)]  # NOP after a command unless another follows
    vcd.record(
        scope,
        "cmd",
        4,
        np.concatenate([t, idle]),
        np.concatenate([trace["cmd"], np.full(idle.size, COMMANDS["NOP"])]),
    )
    vcd.record(scope, "ba", 2, t, trace["bank"])
    vcd.record(scope, "a", 13, t, trace["a"])
    vcd.record(scope, "commands", 32, t, np.arange(1, t.size + 1))


def read_vcd_commands(path) -> dict[int, np.ndarray]:
    """The command traces :func:`record_commands` wrote into the VCD at ``path``, by
    module (scopes ``memory_K.sdram``): :data:`TRACE_DTYPE` records.  A command is a
    change of ``commands``; ``cmd``, ``ba`` and ``a`` are their values at that time."""
    with open(path) as handle:
        text = handle.read()
    head, _, body = text.partition("$enddefinitions")
    ids: dict[str, tuple[int, str]] = {}
    scopes: list[str] = []
    for line in head.splitlines():
        word = line.split()
        if word[:1] == ["$scope"]:
            scopes.append(word[2])
        elif word[:1] == ["$upscope"]:
            scopes.pop()
        elif word[:1] == ["$var"] and len(scopes) >= 2 and scopes[-1] == "sdram":
            if scopes[-2].startswith("memory_"):
                ids[word[3]] = (int(scopes[-2].split("_")[1]), word[4])
    changes: dict[tuple[int, str], tuple[list[int], list[int]]] = {
        key: ([], []) for key in ids.values()
    }
    now = 0
    for line in body.splitlines()[1:]:
        if line.startswith("#"):
            now = int(line[1:])
        elif line.startswith("b"):
            value, _, ident = line.partition(" ")
            key = ids.get(ident)
            if key is not None:
                changes[key][0].append(now)
                changes[key][1].append(int(value[1:], 2))
    out = {}
    for k in sorted({k for k, _ in ids.values()}):
        times = np.asarray(changes.get((k, "commands"), ([], []))[0], dtype=np.int64)
        trace = np.zeros(times.size, dtype=TRACE_DTYPE)
        trace["cycle"] = times
        for field, name, idle in (
            ("cmd", "cmd", COMMANDS["NOP"]),
            ("bank", "ba", 0),
            ("a", "a", 0),
        ):
            at, values = (np.asarray(v, dtype=np.int64) for v in changes.get((k, name), ([], [])))
            last = np.searchsorted(at, times, side="right") - 1  # the value at each command
            trace[field] = np.where(
                last >= 0, values[np.maximum(last, 0)] if at.size else idle, idle
            )
        out[k] = trace
    return out
