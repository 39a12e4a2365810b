"""An independent checker of SDRAM command schedules (used by the memory tests).

It replays the commands of a :class:`hwsim.memory.BurstSchedule` in time order against a
per-bank state machine and lists every broken rule.  It shares no code with the model:
only the schedule arrays and the configuration go in.
"""

from __future__ import annotations

import numpy as np

from hwsim.memory import CONFLICT, HIT, SdramConfig

PRE, PREA, REF, ACT, READ = "PRE", "PREA", "REF", "ACT", "READ"
_PRIORITY = {PRE: 0, PREA: 0, REF: 1, ACT: 2, READ: 3}


def violations(
    cfg: SdramConfig, bank, row, earliest, sched, *, command_bus: bool = True
) -> list[str]:
    """Every timing rule the schedule breaks (empty: a legal schedule)."""
    bank = np.asarray(bank, dtype=np.int64)
    row = np.asarray(row, dtype=np.int64)
    n = bank.size
    earliest = np.zeros(n, dtype=np.int64) if earliest is None else np.asarray(earliest)
    bad: list[str] = []
    bc = cfg.burst_length // cfg.data_rate
    read, act, pre = sched.read, sched.activate, sched.precharge

    events = []
    for i in range(n):
        if pre[i] >= 0:
            events.append((int(pre[i]), PRE, i))
        if act[i] >= 0:
            events.append((int(act[i]), ACT, i))
        events.append((int(read[i]), READ, i))
    for k, (prea, ref) in enumerate(sched.refresh.tolist()):
        if prea >= 0:
            events.append((prea, PREA, k))
        events.append((ref, REF, k))
    times = [t for t, _, _ in events]
    if command_bus and len(set(times)) != len(times):
        bad.append("two commands share a command-bus cycle")
    events.sort(key=lambda e: (e[0], _PRIORITY[e[1]]))

    never = -(1 << 40)
    open_row = [-1] * cfg.banks
    t_act = [never] * cfg.banks
    t_pre = [never] * cfg.banks
    t_read = [never] * cfg.banks
    last_act = never
    busy_until = never  # no command before the end of tRFC
    for t, kind, i in events:
        if t < busy_until:
            bad.append(f"{kind} at {t} during refresh (until {busy_until})")
        if kind in (PRE, ACT, READ) and t < earliest[i]:
            bad.append(f"{kind} of request {i} at {t} before its earliest {earliest[i]}")
        if kind == PRE:
            b = bank[i]
            if open_row[b] < 0:
                bad.append(f"PRE of request {i} on closed bank {b}")
            if t < t_act[b] + cfg.t_ras:
                bad.append(f"PRE of request {i} at {t} breaks tRAS")
            if t < t_read[b] + bc:
                bad.append(f"PRE of request {i} at {t} cuts a burst short")
            open_row[b], t_pre[b] = -1, t
        elif kind == PREA:
            for b in range(cfg.banks):
                if open_row[b] >= 0:
                    if t < t_act[b] + cfg.t_ras or t < t_read[b] + bc:
                        bad.append(f"PRECHARGE-ALL at {t} breaks tRAS or a burst of bank {b}")
                    open_row[b], t_pre[b] = -1, t
        elif kind == REF:
            for b in range(cfg.banks):
                if open_row[b] >= 0 or t < t_pre[b] + cfg.t_rp:
                    bad.append(f"REFRESH at {t} with bank {b} not precharged")
                t_pre[b] = max(t_pre[b], t + cfg.t_rfc - cfg.t_rp)
            busy_until = t + cfg.t_rfc
            if cfg.t_refi and t < (i + 1) * cfg.t_refi:
                bad.append(f"refresh {i + 1} at {t} before it is due")
        elif kind == ACT:
            b = bank[i]
            if open_row[b] >= 0:
                bad.append(f"ACT of request {i} on open bank {b}")
            if t < t_pre[b] + cfg.t_rp:
                bad.append(f"ACT of request {i} at {t} breaks tRP")
            if t < t_act[b] + cfg.t_rc:
                bad.append(f"ACT of request {i} at {t} breaks tRC")
            if t < last_act + cfg.t_rrd:
                bad.append(f"ACT of request {i} at {t} breaks tRRD")
            open_row[b], t_act[b], last_act = row[i], t, t
        else:  # READ
            b = bank[i]
            if open_row[b] != row[i]:
                bad.append(f"READ of request {i} while bank {b} has row {open_row[b]} open")
            if t < t_act[b] + cfg.t_rcd:
                bad.append(f"READ of request {i} at {t} breaks tRCD")
            t_read[b] = t
            if cfg.page_policy == "closed":  # auto-precharge
                open_row[b] = -1
                t_pre[b] = max(t + bc, t_act[b] + cfg.t_ras)

    if n:
        if np.any(np.diff(read) < bc):
            bad.append("data bursts overlap or READs out of order")
        acts = act[act >= 0]
        if np.any(np.diff(acts) < (1 if command_bus else 0)):
            bad.append("ACTIVATEs out of request order")
        if np.any((act < 0) != (sched.outcome == HIT)):
            bad.append("row hits must be exactly the requests without ACTIVATE")
        if np.any((pre >= 0) != (sched.outcome == CONFLICT)):
            bad.append("conflicts must be exactly the requests with PRECHARGE")
        if np.any(sched.data_first != read + cfg.cas_latency):
            bad.append("first beat is not READ + CL")
    if cfg.t_refi and n:
        # Refresh k is done before any command of a request admitted after it fell due;
        # admission is at least the arrival and the READ of request i - queue_depth, + 1.
        ref_end = sched.refresh[:, 1] + cfg.t_rfc
        for i in range(n):
            admitted = int(earliest[i])
            if i >= cfg.queue_depth:
                admitted = max(admitted, int(read[i - cfg.queue_depth]) + 1)
            first = min(int(v) for v in (pre[i], act[i], read[i]) if v >= 0)
            owed = admitted // cfg.t_refi
            if np.count_nonzero(ref_end <= first) < owed:
                bad.append(f"request {i} issues at {first} with refresh {owed} still owed")
                break
    return bad
