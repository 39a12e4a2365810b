"""SimPy discrete-event form of the SDRAM model, at burst granularity.

# Ref: shared/docs/reference/architectures.md section 9.1 (SDRAM burst scheduling, bank
#      interleave, refresh) and design.md section 3 (the `transaction` rung: a SimPy
#      event model at beam/burst granularity).

Same parameters (:class:`~hwsim.memory.sdram.SdramConfig`) and the same rules as the
cycle-exact form (:mod:`hwsim.memory.sdram_cycle`), expressed as cooperating SimPy
processes that exchange events instead of a loop over requests:

* a **controller** takes requests from the module's :class:`simpy.Store` in order,
  admits request ``i`` once request ``i - queue_depth`` has read, refreshes first when the
  admission falls at or after a refresh's due cycle (PRECHARGE-ALL, tRP, REFRESH, tRFC,
  after the last issued READ), and classifies the request hit / miss / conflict from the
  rows requested before it;
* one **bank process** per bank serves that bank's requests in order: it times
  PRECHARGE and ACTIVATE with timeouts (tRAS, read-to-precharge, tRP, tRC, tRRD after the
  previous request's ACTIVATE) and signals *row ready* tRCD later;
* a **data-bus sequencer** issues the READs in request order, ``burst_cycles`` apart, and
  fires each request's ``done`` event after its last beat.

Simulated time is memory-clock cycles.  What it leaves out, by design, is the *command
bus*: PRECHARGE, ACTIVATE and READ of different requests may share a cycle, where the
cycle form moves the later one to the next free cycle.  On streams without such
collisions the two forms agree cycle for cycle; docs/memory.md gives the measured
difference where they do collide.

No rung uses :class:`SdramEventModel` itself (the transaction rung takes the batch
port below): it stays as the event-driven statement of the SDRAM rules, held against the
cycle-exact form as an independent reference by ``tests/memory/test_sdram_events.py``.

Embedding in a larger model: create :class:`SdramEventModel` on the caller's
``simpy.Environment`` and call :meth:`SdramEventModel.request` from any process; wait on
the returned request's ``done`` (or ``read_done``) event.

Coarser and faster: :class:`SdramTransactionPort` takes a whole batch of bursts (a beam)
per call and returns one event, timed by the cycle-exact controller, so a
transaction-level model pays one SimPy event per batch, not about thirteen per burst;
:meth:`SdramTransactionPort.read_runs` queues several batches, each burst from its own
arrival cycle, in one call and returns their end cycles, for a model that times its own
events (and may hand the controller its bursts later than they arrived: the controller is
causal).
"""

from __future__ import annotations

import numpy as np
import simpy

from hwsim.memory.sdram import SdramConfig
from hwsim.memory.sdram_cycle import (
    CONFLICT,
    HIT,
    MISS,
    BurstSchedule,
    SdramController,
    summarize,
)

__all__ = ["BurstRequest", "SdramEventModel", "SdramTransactionPort", "simulate_events"]

_NEVER = -(1 << 40)


class BurstRequest:
    """One burst in flight: its place in the stream, its target and its events.

    Attributes
    ----------
    index, bank, row, earliest : int
    acted, ready, read_done, done : simpy.Event
        ACTIVATE issued (never, for a row hit); row open; READ issued;
        last data beat delivered (fires at ``read + CL + burst_cycles``).
    kind, precharge, activate, read : int
        Filled in as the request is served (-1: no such command).
    """

    __slots__ = (
        "acted",
        "activate",
        "after",
        "bank",
        "done",
        "earliest",
        "index",
        "kind",
        "precharge",
        "read",
        "read_done",
        "ready",
        "refreshed",
        "row",
    )

    def __init__(self, env: simpy.Environment, index: int, bank: int, row: int) -> None:
        self.index, self.bank, self.row = index, bank, row
        self.earliest = int(env.now)
        self.acted = env.event()
        self.ready = env.event()
        self.read_done = env.event()
        self.done = env.event()
        self.kind = HIT
        self.precharge = self.activate = self.read = -1
        self.refreshed = False
        self.after: BurstRequest | None = None  # the previous request that activates


class SdramEventModel:
    """One SDRAM device as SimPy processes (see the module docstring).

    Parameters
    ----------
    env : simpy.Environment
        Time unit: one memory clock.
    cfg : SdramConfig
    """

    def __init__(self, env: simpy.Environment, cfg: SdramConfig) -> None:
        self.env = env
        self.cfg = cfg
        self.requests: list[BurstRequest] = []
        self.refresh_log: list[tuple[int, int]] = []
        self._incoming = simpy.Store(env)
        self._to_bank = [simpy.Store(env) for _ in range(cfg.banks)]
        self._to_bus = simpy.Store(env)
        nb = cfg.banks
        self.open_row = [-1] * nb  # rows open in the device now
        self._planned_row = [-1] * nb  # rows open once every admitted request has read
        self._last_activating: BurstRequest | None = None
        self.act_at = [_NEVER] * nb
        self.act_ready = [0] * nb
        self.read_at = [_NEVER] * nb
        self.prev_read = _NEVER
        self.last_act = _NEVER  # ACTIVATEs issue in request order (each waits the last)
        self.last_cmd = -1
        self.refresh_end = 0
        self.due = cfg.t_refi if cfg.t_refi > 0 else float("inf")
        env.process(self._controller())
        env.process(self._sequencer())
        for b in range(nb):
            env.process(self._bank(b))

    def request(self, bank: int, row: int) -> BurstRequest:
        """Queue a burst now (``env.now`` is its earliest cycle); returns its events."""
        if not (0 <= bank < self.cfg.banks and 0 <= row < self.cfg.rows):
            raise ValueError(f"bank {bank} / row {row} outside the device")
        req = BurstRequest(self.env, len(self.requests), bank, row)
        self.requests.append(req)
        self._incoming.put(req)
        return req

    # -- processes ---------------------------------------------------------------------

    def _wait_until(self, t: int):
        if t > self.env.now:
            yield self.env.timeout(t - self.env.now)

    def _controller(self):
        cfg, env = self.cfg, self.env
        depth = cfg.queue_depth
        while True:
            req = yield self._incoming.get()
            i = req.index
            if i >= depth:
                older = self.requests[i - depth]
                yield older.read_done
                yield from self._wait_until(older.read + 1)
            while env.now >= self.due:
                req.refreshed = True
                if i:
                    yield self.requests[i - 1].read_done  # every earlier command issued
                self._refresh()
                yield from self._wait_until(self.refresh_end)
            # Admitted: hit, miss or conflict follows from the rows requested so far.
            b = req.bank
            planned = self._planned_row[b]
            if planned == req.row:
                req.kind = HIT
            else:
                req.kind = MISS if planned < 0 else CONFLICT
                req.after = self._last_activating  # ACTIVATEs go in request order
                self._last_activating = req
            if cfg.page_policy == "open":
                self._planned_row[b] = req.row
            self._to_bank[b].put(req)
            self._to_bus.put(req)

    def _refresh(self) -> None:
        """Book a refresh after every issued command (its cycles may lie in the past when
        the controller sat idle: the device was idle then, so nothing else changes)."""
        cfg = self.cfg
        start = max(self.due, self.last_cmd + 1)
        prea = -1
        open_banks = [k for k in range(cfg.banks) if self.open_row[k] >= 0]
        if open_banks:
            for k in open_banks:
                start = max(
                    start, self.act_at[k] + cfg.t_ras, self.read_at[k] + cfg.read_to_precharge
                )
            prea = start
            ref = prea + cfg.t_rp
        else:
            ref = start
        ref = max(ref, *self.act_ready)
        self.refresh_log.append((prea, ref))
        self.last_cmd = ref
        self.refresh_end = ref + cfg.t_rfc
        for k in range(cfg.banks):
            self.open_row[k] = self._planned_row[k] = -1
            self.act_ready[k] = self.refresh_end
        self.due += cfg.t_refi

    def _bank(self, b: int):
        cfg, env = self.cfg, self.env
        while True:
            req = yield self._to_bank[b].get()
            if req.kind == HIT:
                yield from self._wait_until(self.act_at[b] + cfg.t_rcd)
                req.ready.succeed()
                yield req.read_done  # the bank serves its next request after this READ
                continue
            if req.kind == CONFLICT:
                yield from self._wait_until(
                    max(self.act_at[b] + cfg.t_ras, self.read_at[b] + cfg.read_to_precharge)
                )
                req.precharge = int(env.now)
                yield env.timeout(cfg.t_rp)
            else:
                yield from self._wait_until(self.act_ready[b])
            if req.after is not None:
                yield req.after.acted  # ACTIVATEs in request order
            yield from self._wait_until(max(self.act_at[b] + cfg.t_rc, self.last_act + cfg.t_rrd))
            req.activate = int(env.now)
            self.act_at[b] = self.last_act = req.activate
            req.acted.succeed()
            yield env.timeout(cfg.t_rcd)
            req.ready.succeed()
            yield req.read_done

    def _sequencer(self):
        cfg, env = self.cfg, self.env
        tail = cfg.cas_latency + cfg.burst_cycles
        while True:
            req = yield self._to_bus.get()
            yield req.ready
            yield from self._wait_until(self.prev_read + cfg.burst_cycles)
            t = int(env.now)
            req.read = t
            b = req.bank
            self.prev_read = t
            self.last_cmd = max(self.last_cmd, t)
            self.read_at[b] = t
            if cfg.page_policy == "closed":
                self.open_row[b] = -1
                self.act_ready[b] = (
                    max(t + cfg.read_to_precharge, self.act_at[b] + cfg.t_ras) + cfg.t_rp
                )
            else:
                self.open_row[b] = req.row
            req.read_done.succeed()
            env.timeout(tail).callbacks.append(lambda _e, r=req: r.done.succeed())

    # -- results -----------------------------------------------------------------------

    def schedule(self) -> BurstSchedule:
        """The commands and counters of every request served so far (same form as
        :func:`hwsim.memory.schedule_bursts`)."""
        reqs = [r for r in self.requests if r.read >= 0]
        return summarize(
            self.cfg,
            read=[r.read for r in reqs],
            activate=[r.activate for r in reqs],
            precharge=[r.precharge for r in reqs],
            outcome=[r.kind for r in reqs],
            earliest=[r.earliest for r in reqs],
            refreshed_before=[r.refreshed for r in reqs],
            refresh_log=self.refresh_log,
        )


class SdramTransactionPort:
    """A SimPy front end of the cycle-exact controller: one event per batch of bursts.

    Every burst of a batch is queued at the call's ``env.now`` (rounded up to a whole
    memory cycle); :class:`~hwsim.memory.SdramController` gives the exact cycles, so the
    timing is the cycle form's for those arrival cycles.  ``env`` and ``cfg`` as
    :class:`SdramEventModel` (one memory clock per time unit).
    """

    def __init__(self, env: simpy.Environment, cfg: SdramConfig) -> None:
        self.env = env
        self.controller = SdramController(cfg)

    def read(self, bank, row) -> simpy.Event:
        """Queue a batch of bursts now.

        Returns
        -------
        simpy.Event
            Fires at the cycle after the batch's last data beat; its value is the
            ``(first, last)`` request indices of the batch in the port's stream.
        """
        ctl = self.controller
        first = len(ctl)
        now = -(-self.env.now // 1)
        count = len(bank)
        ctl.issue_many(bank, row, at=int(now))
        if count == 0:
            return self.env.timeout(0, value=(first, first - 1))
        end = ctl.data_end(first + count - 1)
        return self.env.timeout(end - self.env.now, value=(first, first + count - 1))

    def read_runs(self, bank, row, arrive, ends) -> np.ndarray:
        """Queue, in one call, consecutive batches the caller has already checked against
        the device (banks ``0 .. banks-1``, rows ``0 .. rows-1``), each burst from its own
        arrival cycle: the same schedule as one :meth:`read` per batch at that cycle (the
        controller schedules any split of a stream alike, and a burst's cycles depend only
        on the bursts before it), without a check or an event per batch.

        Parameters
        ----------
        bank, row, arrive : numpy.ndarray
            int64, every batch's bursts concatenated in read order; ``arrive`` ascending.
        ends : array of int
            Ascending: batch ``i`` is bursts ``ends[i - 1] .. ends[i] - 1`` (from 0).

        Returns
        -------
        numpy.ndarray
            int64 per batch, the cycle after its last data beat (0 for an empty batch);
            the caller times its own events from these.
        """
        ctl = self.controller
        first = len(ctl)
        if len(bank):
            ctl._run(bank, row, arrive)
        ends = np.asarray(ends, dtype=np.int64)
        out = np.zeros(ends.shape[0], dtype=np.int64)
        full = ends > np.concatenate(([0], ends[:-1]))
        if full.any():
            out[full] = ctl.reads[first + ends[full] - 1] + ctl.cfg.cas_latency
            out[full] += ctl.cfg.burst_cycles
        return out

    def schedule(self) -> BurstSchedule:
        """Commands and counters of every burst read so far."""
        return self.controller.schedule()


def simulate_events(cfg: SdramConfig, bank, row, earliest=None) -> BurstSchedule:
    """Run a request stream through :class:`SdramEventModel` on its own environment.

    Same arguments and result as :func:`hwsim.memory.schedule_bursts`.
    """
    banks = [int(v) for v in bank]
    rows = [int(v) for v in row]
    arrive = [0] * len(banks) if earliest is None else [int(v) for v in earliest]
    if len(rows) != len(banks) or len(arrive) != len(banks):
        raise ValueError("bank, row and earliest must have the same length")
    if any(a < 0 for a in arrive):
        raise ValueError("earliest out of range 0 .. inf")
    env = simpy.Environment()
    model = SdramEventModel(env, cfg)

    def feed():
        for b, r, a in zip(banks, rows, arrive, strict=True):
            if a > env.now:
                yield env.timeout(a - env.now)
            model.request(b, r).earliest = a

    env.process(feed())
    env.run()
    return model.schedule()
