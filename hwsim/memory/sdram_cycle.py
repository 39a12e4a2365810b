"""Cycle-exact SDRAM timing: the exact cycle of every command and data beat of a burst stream.

# Ref: shared/docs/reference/architectures.md section 9.1 (voxel memory controller: SDRAM
#      burst scheduling, bank interleave, refresh) and 9.5 item 2 (bursts back-to-back);
#      the timing rules are the JEDEC SDR SDRAM ones every PC100/PC133 datasheet states.

The model is a read-only, in-order memory controller driving one SDRAM device (one memory
module).  It is exact at the clock: every PRECHARGE, ACTIVATE, READ and REFRESH command
gets an integer memory-clock cycle, one command per cycle on the command bus, and every
timing rule of :class:`~hwsim.memory.sdram.SdramConfig` holds between them (the property
tests replay the command log against an independent checker).  It loops over *requests*,
not cycles, whatever the gaps between them; the loop is compiled
(:mod:`hwsim.memory.sdram_kernel`).

Rules, for request ``i`` to bank ``b``, row ``r``, not before cycle ``earliest[i]``:

* **Order.** Requests enter the controller in order: request ``i`` is *admitted* at
  ``max(earliest[i], admission of i - 1, READ of i - queue_depth + 1)`` (the controller
  holds ``queue_depth`` requests) and issues no command before.  READs issue in request
  order, each at least ``burst_cycles`` after the previous one (the data bus is busy
  ``burst_cycles`` per burst; CAS latency is the same for all); ACTIVATEs issue in request
  order too, tRRD apart.  Within the window the PRECHARGE and ACTIVATE of request ``i``
  overlap the bursts of earlier requests to other banks (bank interleaving).
* **Row hit** (row ``r`` open in ``b``): READ >= ACT(b) + tRCD.
* **Row miss** (bank closed): ACT >= PRE(b) + tRP, ACT(b) + tRC, last ACT + tRRD; READ >=
  ACT + tRCD.
* **Row conflict** (another row open): PRE >= ACT(b) + tRAS and >= last READ(b) +
  ``burst_cycles`` (a PRECHARGE may not cut the burst short); then as a miss.
* **Closed page policy**: every READ auto-precharges; the bank is ready to activate
  ``tRP`` after ``max(READ + burst_cycles, ACT + tRAS)``; every request is a miss.
* **Refresh.** Refresh ``k`` falls due at ``k * t_refi``.  A request admitted at or after
  the due cycle waits for the refresh: at ``max(due, last command + 1)`` (so during idle
  time if the controller was idle) the controller precharges all open banks (one
  PRECHARGE-ALL, honouring tRAS and the bursts in flight), waits tRP, issues REFRESH and
  then nothing for tRFC; every bank is then closed.  No request, no refresh: the stream's
  end is not padded.
* **Data.** READ at ``t``: beats at ``t + CL .. t + CL + burst_cycles - 1``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from hwsim.memory.sdram import SdramConfig
from hwsim.memory.sdram_kernel import (
    BANK_ROWS,
    CONFLICT,
    HIT,
    MISS,
    REGS,
    empty_out,
    log_counts,
    outcomes,
    outcomes_and_gaps,
    schedule_requests,
)

__all__ = [
    "HIT",
    "MISS",
    "CONFLICT",
    "BurstSchedule",
    "SdramController",
    "SdramStats",
    "schedule_bursts",
    "summarize",
]

_NEVER = -(1 << 40)
REFRESHES = REGS.index("refreshes")


@dataclass(frozen=True, kw_only=True)
class SdramStats:
    """Raw counters of one memory module (memory-clock cycles).

    ``elapsed_cycles = data_busy_cycles + first_access_cycles + stall_arrival_cycles +
    stall_bank_cycles + stall_refresh_cycles``: every data-bus idle cycle after the first
    beat is charged to one cause (the request was not there yet; bank timing, command-bus
    slots or the controller queue; a refresh).
    """

    bursts: int = 0
    row_hits: int = 0
    row_misses: int = 0
    row_conflicts: int = 0
    activates: int = 0
    precharges: int = 0
    refreshes: int = 0
    refresh_cycles: int = 0
    data_busy_cycles: int = 0
    idle_cycles: int = 0
    elapsed_cycles: int = 0
    first_access_cycles: int = 0
    stall_arrival_cycles: int = 0
    stall_bank_cycles: int = 0
    stall_refresh_cycles: int = 0

    @property
    def efficiency(self) -> float:
        """Data-bus busy cycles / elapsed cycles (1.0: bursts back-to-back from cycle 0)."""
        return self.data_busy_cycles / self.elapsed_cycles if self.elapsed_cycles else 0.0

    @property
    def streaming_efficiency(self) -> float:
        """Busy / (elapsed - first access latency): the steady-state share of the data bus."""
        span = self.elapsed_cycles - self.first_access_cycles
        return self.data_busy_cycles / span if span > 0 else 0.0

    def to_counters(self, prefix: str = "memory") -> dict[str, int]:
        """Counters under a component path, e.g. ``memory[2].row_hits``."""
        return {f"{prefix}.{f.name}": getattr(self, f.name) for f in fields(self)}

    @staticmethod
    def combine(parts: list[SdramStats]) -> SdramStats:
        """Totals of several modules working in parallel: sums, ``elapsed`` = the longest."""
        sums: dict[str, Any] = {
            f.name: sum(getattr(p, f.name) for p in parts) for f in fields(SdramStats)
        }
        sums["elapsed_cycles"] = max((p.elapsed_cycles for p in parts), default=0)
        return SdramStats(**sums)


@dataclass(frozen=True)
class BurstSchedule:
    """Result of :func:`schedule_bursts`: per-request command cycles and the counters.

    Attributes
    ----------
    read, activate, precharge : numpy.ndarray
        int64 per request: cycle of its READ, of its ACTIVATE (-1: none, row hit) and of its
        PRECHARGE (-1: none; the auto-precharge of the closed policy is not a command).
    data_first, data_end : numpy.ndarray
        First data beat ``read + CL`` and the cycle after the last, ``data_first +
        burst_cycles``.
    outcome : numpy.ndarray
        int8: :data:`HIT`, :data:`MISS` or :data:`CONFLICT`.
    refresh : numpy.ndarray
        int64 ``(k, 2)``: cycle of each refresh's PRECHARGE-ALL (-1 when every bank was
        already closed) and of its REFRESH command.
    stats : SdramStats
    """

    read: np.ndarray
    activate: np.ndarray
    precharge: np.ndarray
    data_first: np.ndarray
    data_end: np.ndarray
    outcome: np.ndarray
    refresh: np.ndarray
    stats: SdramStats

    @property
    def cycles(self) -> int:
        """Cycle after the last data beat (0 for an empty stream)."""
        return self.stats.elapsed_cycles


def _checked(name: str, values, n: int, lo: int, hi: int | None) -> np.ndarray:
    arr = np.asarray(values, dtype=np.int64).reshape(-1)
    if arr.size != n:
        raise ValueError(f"{name} has {arr.size} entries, expected {n}")
    if arr.size and (arr.min() < lo or (hi is not None and arr.max() > hi)):
        raise ValueError(f"{name} out of range {lo} .. {hi if hi is not None else 'inf'}")
    return arr


def schedule_bursts(
    cfg: SdramConfig, bank, row, earliest=None, *, command_bus: bool = True
) -> BurstSchedule:
    """Schedule an ordered stream of READ bursts on one SDRAM device, cycle-exactly.

    Parameters
    ----------
    cfg : SdramConfig
    bank, row : array of int
        Per request, in issue order: the bank (``0 .. banks-1``) and row (``0 .. rows-1``).
        The column does not change the timing (any column of an open row reads alike).
    earliest : array of int, optional
        Per request, the first memory cycle it may issue a command (e.g. when the FIFO it
        fills has space); default 0 for all (the memory-bound case).
    command_bus : bool
        Enforce one command per cycle (the device's rule).  ``False`` lets commands share
        a cycle, which is what the burst-granularity SimPy form assumes; the tests use it
        to show the two forms differ by that rule only.

    Returns
    -------
    BurstSchedule
    """
    controller = SdramController(cfg, command_bus=command_bus)
    controller.issue_many(bank, row, earliest)
    return controller.schedule()


class SdramController:
    """The cycle-exact scheduler as an object that takes requests a few at a time.

    For a caller whose next request depends on earlier completions (a FIFO that frees a
    slot when the consumer has used a burst): :meth:`issue` one request, read its
    :meth:`data_end`, compute the next ``earliest``.  Any split of a stream into
    :meth:`issue` / :meth:`issue_many` calls gives the same schedule as
    :func:`schedule_bursts` on the whole stream.

    Parameters
    ----------
    cfg : SdramConfig
    command_bus : bool
        As in :func:`schedule_bursts`.
    """

    def __init__(self, cfg: SdramConfig, *, command_bus: bool = True) -> None:
        self.cfg = cfg
        self.command_bus = command_bus
        self._params = np.array(
            [
                cfg.t_rcd,
                cfg.t_rp,
                cfg.t_ras,
                cfg.t_rc,
                cfg.t_rrd,
                cfg.burst_cycles,
                cfg.read_to_precharge,
                cfg.t_rfc,
                cfg.t_refi,
                cfg.page_policy == "closed",
                cfg.queue_depth,
                command_bus,
            ],
            dtype=np.int64,
        )
        due = cfg.t_refi if cfg.t_refi > 0 else 1 << 62
        # last_act, prev_read, last_ref, refresh_end, due, floor, booked, refreshes
        self._regs = np.array([_NEVER, _NEVER, -1, 0, due, 0, 0, 0], dtype=np.int64)
        self._banks = np.empty((len(BANK_ROWS), cfg.banks), dtype=np.int64)
        # open_row (-1: closed), last ACTIVATE, earliest ACTIVATE, last READ per bank
        self._banks[:] = np.array([-1, _NEVER, 0, _NEVER], dtype=np.int64)[:, None]
        self._out = empty_out(64)  # per request: READ, ACTIVATE, PRECHARGE, refreshed
        self._arrivals = np.zeros(64, dtype=np.int64)
        self._booked = np.zeros(16, dtype=np.int64)  # command-bus cycles (recent ones)
        self._log = np.zeros((16, 2), dtype=np.int64)  # per refresh: PRECHARGE-ALL, REFRESH
        self._n = 0
        self._kernel = schedule_requests  # its ``py_func`` runs the same loop uncompiled

    def __len__(self) -> int:
        return self._n

    @property
    def reads(self) -> np.ndarray:
        """READ cycle of every request issued so far (a view)."""
        return self._out[0, : self._n]

    def issue(self, bank: int, row: int, earliest: int = 0) -> int:
        """Schedule one request; returns the cycle of its READ."""
        cfg = self.cfg
        if not (0 <= bank < cfg.banks and 0 <= row < cfg.rows and earliest >= 0):
            raise ValueError(
                f"bank {bank}, row {row}, earliest {earliest} out of range "
                f"(bank 0 .. {cfg.banks - 1}, row 0 .. {cfg.rows - 1}, earliest >= 0)"
            )
        self._run([int(bank)], [int(row)], [int(earliest)])
        return int(self._out[0, self._n - 1])

    def data_end(self, index: int) -> int:
        """Cycle after the last data beat of request ``index``."""
        return int(self._out[0, index]) + self.cfg.cas_latency + self.cfg.burst_cycles

    def issue_many(self, bank, row, earliest=None, *, at: int | None = None) -> None:
        """Schedule a batch of requests (arrays as in :func:`schedule_bursts`); ``at``
        instead of ``earliest``: every request may issue from that one cycle."""
        n = int(np.asarray(bank).size)
        banks = _checked("bank", bank, n, 0, self.cfg.banks - 1)
        rows = _checked("row", row, n, 0, self.cfg.rows - 1)
        if at is not None:
            if at < 0:
                raise ValueError(f"earliest out of range 0 .. inf: {at}")
            arrive = np.full(n, at, dtype=np.int64)
        elif earliest is None:
            arrive = np.zeros(n, dtype=np.int64)
        else:
            arrive = _checked("earliest", earliest, n, 0, None)
        self._run(banks, rows, arrive)

    def schedule(self, *, copy: bool = True) -> BurstSchedule:
        """Commands and counters of every request issued so far (int64 copies).
        ``copy=False`` hands out views of the controller's arrays (int32 when a frame's
        compiled loop held them narrow), for a caller that issues nothing more (a 512^3
        frame's copies were 32 bytes a burst at the frame's memory peak)."""
        n = self._n
        read, act_arr, pre_arr = (
            self._out[k, :n].astype(np.int64) if copy else self._out[k, :n] for k in range(3)
        )
        return summarize(
            self.cfg,
            read=read,
            activate=act_arr,
            precharge=pre_arr,
            outcome=outcomes(act_arr, pre_arr),
            earliest=self._arrivals[:n].astype(np.int64) if copy else self._arrivals[:n],
            refreshed_before=self._out[3, :n] != 0,
            refresh_log=self._log[: self._regs[REFRESHES]].copy(),
        )

    def stats(self) -> SdramStats:
        """:meth:`schedule`'s ``stats`` alone (no command arrays): one compiled pass over
        the logs for the outcomes and gaps, the rest as :func:`summarize` counts them."""
        n, out, cfg = self._n, self._out, self.cfg
        counts, stalls = log_counts(
            out, self._arrivals, n, cfg.burst_cycles, cfg.t_rcd, cfg.t_rp + cfg.t_rcd
        )
        refresh = self._log[: self._regs[REFRESHES]]
        reads = (int(out[0, 0]), int(out[0, n - 1])) if n else None
        return _stats(cfg, n, counts, stalls, reads, refresh)

    def reserve(self, n: int) -> None:
        """Make room for ``n`` more requests at once (a caller that knows its request
        count saves the doubling's slack: 40 bytes a request)."""
        need = self._n + int(n)
        if need > self._arrivals.shape[0]:
            self._widen(need)

    def adopt_logs(self, out: np.ndarray, arrivals: np.ndarray) -> None:
        """Log the requests into ``out`` (int64 ``(4, m)``) and ``arrivals`` (int64
        ``(m,)``) from here on, before the first request: scratch a caller reuses from
        frame to frame (their pages already mapped; a fresh 128^3 VolumePro 1000 frame's
        logs were ~2,000 page faults).  Nothing of their old contents is read: the loop
        writes every entry of a request when it schedules it."""
        if self._n:
            raise RuntimeError("adopt_logs before the first request only")
        rows = self._out.shape[0]
        if out.dtype != np.int64 or arrivals.dtype != np.int64 or out.shape[0] != rows:
            raise ValueError(f"out and arrivals must be int64, out ({rows}, m)")
        if out.shape[1] != arrivals.shape[0]:
            raise ValueError(f"out has {out.shape[1]} columns, arrivals {arrivals.shape[0]}")
        self._out, self._arrivals = out, arrivals

    def logs(self) -> tuple[np.ndarray, np.ndarray]:
        """The request logs (``out``, ``arrivals``), e.g. to reuse once the schedule is
        read (:meth:`adopt_logs`)."""
        return self._out, self._arrivals

    def _widen(self, capacity: int) -> None:
        """Room for ``capacity`` requests, the ones issued so far kept.  The new arrays
        are not filled (``np.resize`` tiled the old arrivals over the whole new one, a
        write of every page; the loop writes each request's entries itself)."""
        n = self._n
        out = np.empty((self._out.shape[0], capacity), dtype=np.int64)
        out[:, :n] = self._out[:, :n]
        arrivals = np.empty(capacity, dtype=np.int64)
        arrivals[:n] = self._arrivals[:n]
        self._out, self._arrivals = out, arrivals

    def _run(self, banks, rows, arrive) -> None:
        """Schedule requests already checked (sequences of int): the compiled loop."""
        banks = np.asarray(banks, dtype=np.int64)
        rows = np.asarray(rows, dtype=np.int64)
        arrive = np.asarray(arrive, dtype=np.int64)
        start, n = self._n, banks.shape[0]
        if start + n > self._arrivals.shape[0]:
            self._widen(max(2 * self._arrivals.shape[0], start + n))
        self._arrivals[start : start + n] = arrive
        self._booked, self._log = self._kernel(
            self._params,
            self._regs,
            self._banks,
            banks,
            rows,
            arrive,
            self._out,
            start,
            self._booked,
            self._log,
        )
        self._n = start + n


def summarize(
    cfg: SdramConfig,
    *,
    read,
    activate,
    precharge,
    outcome,
    earliest,
    refreshed_before,
    refresh_log,
) -> BurstSchedule:
    """Build a :class:`BurstSchedule` and its counters from per-request command cycles.

    Shared by both forms of the model, so their counters mean exactly the same.  The
    data-bus gap before burst ``i > 0`` (``read[i] - read[i-1] - burst_cycles``) is charged
    to *arrival* when the request could not have issued its READ earlier even with its bank
    ready (``earliest + row latency >= read``: 0 for a hit, tRCD for a miss, tRP + tRCD for
    a conflict); else to *refresh* when a refresh came just before request ``i``; otherwise
    to *bank* (row timing, command-bus slots, controller queue).
    """
    read = np.asarray(read, dtype=np.int64).reshape(-1)
    n = read.size
    outcome = np.asarray(outcome, dtype=np.int8).reshape(-1)
    earliest = _integers(earliest)
    refreshed = np.asarray(refreshed_before, dtype=bool).reshape(-1)
    refresh = np.asarray(refresh_log, dtype=np.int64).reshape(-1, 2)
    bc = cfg.burst_cycles
    data_first = read + cfg.cas_latency
    data_end = data_first + bc
    if earliest.size != n or refreshed.size != n:
        raise ValueError(f"earliest and refreshed_before need {n} entries, one a request")
    counts, stalls = outcomes_and_gaps(
        read, outcome, earliest, refreshed, bc, cfg.t_rcd, cfg.t_rp + cfg.t_rcd
    )
    stats = _stats(cfg, n, counts, stalls, (int(read[0]), int(read[-1])) if n else None, refresh)
    return BurstSchedule(
        read=read,
        # As given when already integer arrays: a frame's narrow (int32) controller
        # arrays summarised in place are not widened into copies.
        activate=_integers(activate),
        precharge=_integers(precharge),
        data_first=data_first,
        data_end=data_end,
        outcome=outcome,
        refresh=refresh,
        stats=stats,
    )


def _stats(cfg: SdramConfig, n: int, counts, stalls, reads, refresh) -> SdramStats:
    """:class:`SdramStats` of ``n`` requests from their outcome ``counts``, gap
    ``stalls`` (arrival, bank, refresh), first and last READ cycles ``reads`` (None: no
    request) and refresh log."""
    bc = cfg.burst_cycles
    elapsed = reads[1] + cfg.cas_latency + bc if n else 0
    busy = n * bc
    prea = refresh[:, 0]
    return SdramStats(
        bursts=n,
        row_hits=int(counts[HIT]),
        row_misses=int(counts[MISS]),
        row_conflicts=int(counts[CONFLICT]),
        activates=int(counts[MISS] + counts[CONFLICT]),
        precharges=int(counts[CONFLICT] + np.count_nonzero(prea >= 0)),
        refreshes=int(refresh.shape[0]),
        refresh_cycles=int(
            np.sum(refresh[:, 1] + cfg.t_rfc - np.where(prea >= 0, prea, refresh[:, 1]))
        ),
        data_busy_cycles=busy,
        idle_cycles=elapsed - busy,
        elapsed_cycles=elapsed,
        first_access_cycles=reads[0] + cfg.cas_latency if n else 0,
        stall_arrival_cycles=int(stalls[0]),
        stall_bank_cycles=int(stalls[1]),
        stall_refresh_cycles=int(stalls[2]),
    )


def _integers(values) -> np.ndarray:
    """``values`` as a flat integer array: int32 and int64 arrays as they are, else int64."""
    if isinstance(values, np.ndarray) and values.dtype in (np.int32, np.int64):
        return values.reshape(-1)
    return np.asarray(values, dtype=np.int64).reshape(-1)
