"""The vg500's SDRAM controller: one module's read controller driving an SDR SDRAM's pins.

# Ref: architectures.md sections 3 (VolumePro 500: mini-blocks read as bursts from SDRAM
#      modules) and 9.1 (voxel memory controller: bank state, bursts, refresh); the
#      command encodings, power-up sequence and timing names of any PC100/PC133 SDR SDRAM
#      datasheet (JEDEC 21-C); the pin contract of rtl/sdram/sdr_sdram.v (the sdram_pins contract).

Requests ``(bank, row, col)`` arrive on the ``req`` stream, one burst of ``burst_length``
words each, and are read in order; the words leave on ``rdata_*`` in the same order (no
back-pressure: the consumer has reserved the room).  The controller holds ``QUEUE = 2``
requests: while the head waits for its READ, the second request may PRECHARGE and
ACTIVATE its own bank (bank interleaving), never the head's bank and never ACTIVATE before
the head has its row open (ACTIVATEs in request order).  A slot is refilled the clock
after its READ.  Pages stay open (``a[10] = 0`` on READ).

Every decision is a comparison of the clock counter ``now`` with per-bank time stamps
(last ACTIVATE, last READ, earliest next ACTIVATE) against the device's timings, which
are elaboration parameters taken from the arch file's ``[memory]`` table (the datasheet's
nanoseconds in clocks): nothing else is timed.  One command per clock, in priority:
a refresh's command, the head's, the second request's.

Refresh: due every ``t_refi`` clocks, counted from the end of the power-up sequence and,
once a frame starts (``restart``), from the clock its first request enters the queue:
the frame's refreshes fall at the same clocks of the frame whatever the host did before
it (its table loads; the refreshes of that idle time are issued as they fall due).  The
refresh due between ``restart`` and that first request is postponed to the new phase, one
postponed refresh per frame at most (JEDEC allows eight; the checker counts the debt from
power-up).  Once due, no request is admitted; when the queue is empty the controller
precharges every open bank (PRECHARGE with ``a[10] = 1``, once ``t_ras`` and the bursts
in flight allow), then issues AUTO REFRESH once ``t_rp`` has passed; no bank may activate
for ``t_rfc``.

Power-up: PRECHARGE all, two AUTO REFRESH ``t_rfc`` apart, LOAD MODE (burst length 8,
sequential, the CAS latency), ``T_MRD`` clocks; then ``ready`` rises and ``now`` counts
from 0.  The command pins are registered: a command decided in clock ``c`` is on the pins
in clock ``c + 1``; the device presents read word ``j`` to be sampled ``cas_latency + j``
clocks after the edge that sampled the READ, so the controller captures in clocks
``c + 1 + cas_latency + j``.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth import Array, Module, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from hwsim.memory import SdramConfig

__all__ = ["SdramController", "SdramTiming", "mode_register", "QUEUE", "T_MRD"]

#: Requests the controller holds (the head and one behind it).
QUEUE = 2
#: LOAD MODE to the next command (every PC100/PC133 datasheet: 2 clocks).
T_MRD = 2
#: Commands as ``(cs_n, ras_n, cas_n, we_n)``.
NOP, ACTIVATE, READ, PRECHARGE, REFRESH, LOAD_MODE = 0b0111, 0b0011, 0b0101, 0b0010, 0b0001, 0b0000
#: Time stamps start this far in the past (no earlier command constrains the first).
_NEVER = -(1 << 24)


def mode_register(cas_latency: int, burst_length: int = 8) -> int:
    """The mode register word: burst length code in a[2:0] (8: 3), sequential (a[3] = 0),
    CAS latency in a[6:4], write burst mode a[9] = 0."""
    codes = {1: 0, 2: 1, 4: 2, 8: 3}
    return (cas_latency << 4) | codes[burst_length]


@dataclass(frozen=True, kw_only=True)
class SdramTiming:
    """A device's geometry and timing in clocks (the arch file's ``[memory]`` values)."""

    banks: int = 4
    rows: int = 8192
    columns: int = 512
    word_bits: int = 16
    burst_length: int = 8
    cas_latency: int = 2
    t_rcd: int = 2
    t_rp: int = 2
    t_ras: int = 5
    t_rc: int = 8
    t_rrd: int = 2
    t_rfc: int = 9
    t_refi: int = 976

    @classmethod
    def of(cls, dev: SdramConfig) -> SdramTiming:
        """The timing of ``dev`` (SDR, open pages only)."""
        if dev.data_rate != 1 or dev.page_policy != "open":
            raise ValueError("the vg500 controller drives SDR SDRAM with open pages")
        names = cls.__dataclass_fields__
        return cls(**{k: getattr(dev, k) for k in names})


def request_layout(t: SdramTiming) -> data.StructLayout:
    return data.StructLayout(
        {
            "bank": unsigned(max(1, (t.banks - 1).bit_length())),
            "row": unsigned(max(1, (t.rows - 1).bit_length())),
            "col": unsigned(max(1, (t.columns - 1).bit_length())),
        }
    )


class SdramController(wiring.Component):
    """One module's in-order read controller (see the module docstring).

    Parameters
    ----------
    t : SdramTiming
    init_wait : int
        Clocks of NOP after reset before the power-up sequence (the datasheet's 100 us
        power-up wait; a testbench shortens it).
    """

    def __init__(self, t: SdramTiming, *, init_wait: int = 8):
        self.t, self.init_wait = t, int(init_wait)
        lay = request_layout(t)
        super().__init__(
            {
                "req": In(stream.Signature(lay)),
                "restart": In(1),  # a frame starts: the refresh phase follows its first request
                "rdata_valid": Out(1),
                "rdata_word": Out(t.word_bits),
                "rdata_last": Out(1),
                "ready": Out(1),
                "now": Out(32),
                # decision strobes (a command decided this clock)
                "cmd_activate": Out(1),
                "cmd_read": Out(1),
                "cmd_precharge": Out(1),
                "cmd_refresh": Out(1),
                "admit": Out(1),
                # the SDRAM pins (sdram_pins.md)
                "cke": Out(1),
                "cs_n": Out(1),
                "ras_n": Out(1),
                "cas_n": Out(1),
                "we_n": Out(1),
                "ba": Out(2),
                "a": Out(13),
                "dqm": Out(2),
                "dq_out": Out(16),
                "dq_oe": Out(1),
                "dq_in": In(16),
            }
        )

    def elaborate(self, platform):
        m = Module()
        stamp = signed(34)
        cmd = Signal(4, init=NOP)
        ba = Signal(2)
        addr = Signal(13)
        m.d.comb += [self.dqm.eq(0), self.dq_out.eq(0), self.dq_oe.eq(0)]
        m.d.sync += [
            self.cs_n.eq(cmd[3]),
            self.ras_n.eq(cmd[2]),
            self.cas_n.eq(cmd[1]),
            self.we_n.eq(cmd[0]),
            self.ba.eq(ba),
            self.a.eq(addr),
            self.cke.eq(1),
        ]
        self._power_up(m, cmd, addr)
        now = Signal(stamp)
        m.d.comb += self.now.eq(now)
        with m.If(self.ready):
            m.d.sync += now.eq(now + 1)
        self._commands(m, now, cmd, ba, addr, stamp)
        self._capture(m)
        return m

    def _power_up(self, m, cmd, addr):
        """PRECHARGE all, 2 x AUTO REFRESH, LOAD MODE; then ``ready``."""
        t = self.t
        steps = [
            (None, self.init_wait),
            (PRECHARGE, t.t_rp),
            (REFRESH, t.t_rfc),
            (REFRESH, t.t_rfc),
            (LOAD_MODE, T_MRD),
        ]
        step = Signal(range(len(steps) + 1))
        wait = Signal(range(max(w for _, w in steps) + 1))
        with m.Switch(step):
            for k, (command, clocks) in enumerate(steps):
                with m.Case(k):
                    with m.If(wait == 0):
                        if command is not None:
                            m.d.comb += cmd.eq(command)
                        if command == PRECHARGE:
                            m.d.comb += addr.eq(1 << 10)
                        if command == LOAD_MODE:
                            m.d.comb += addr.eq(mode_register(t.cas_latency, t.burst_length))
                        m.d.sync += wait.eq(clocks - 1)
                        if k == len(steps) - 1:
                            m.d.sync += step.eq(k + 1)
                    with m.Else():
                        m.d.sync += wait.eq(wait - 1)
                        with m.If(wait == 1):
                            m.d.sync += step.eq(k + 1)
            with m.Default():
                m.d.comb += self.ready.eq(wait == 0)
                with m.If(wait != 0):
                    m.d.sync += wait.eq(wait - 1)

    def _commands(self, m, now, cmd, ba, addr, stamp):
        t = self.t
        K, BC = t.banks, t.burst_length
        is_open = Array(Signal(name=f"open{q}") for q in range(K))
        open_row = Array(Signal(13, name=f"row{q}") for q in range(K))
        act_at = Array(Signal(stamp, init=_NEVER, name=f"act_at{q}") for q in range(K))
        read_at = Array(Signal(stamp, init=_NEVER, name=f"read_at{q}") for q in range(K))
        act_ready = Array(Signal(stamp, name=f"act_ready{q}") for q in range(K))
        last_act = Signal(stamp, init=_NEVER)
        prev_read = Signal(stamp, init=_NEVER)
        due = Signal(stamp, init=t.t_refi if t.t_refi > 0 else (1 << 32))
        lay = request_layout(t)
        slot = [Signal(lay, name=f"slot{k}") for k in range(QUEUE)]
        valid = [Signal(name=f"valid{k}") for k in range(QUEUE)]
        a, b = slot
        hit_a = is_open[a.bank] & (open_row[a.bank] == a.row)
        hit_b = is_open[b.bank] & (open_row[b.bank] == b.row)

        def may_precharge(bank):
            return (now >= act_at[bank] + t.t_ras) & (now >= read_at[bank] + BC)

        def may_activate(bank):
            return (
                (now >= act_ready[bank])
                & (now >= act_at[bank] + t.t_rc)
                & (now >= last_act + t.t_rrd)
            )

        def activate(bank, row):
            m.d.comb += [cmd.eq(ACTIVATE), ba.eq(bank), addr.eq(row), self.cmd_activate.eq(1)]
            m.d.sync += [
                is_open[bank].eq(1),
                open_row[bank].eq(row),
                act_at[bank].eq(now),
                last_act.eq(now),
            ]

        def precharge(bank):
            m.d.comb += [cmd.eq(PRECHARGE), ba.eq(bank), self.cmd_precharge.eq(1)]
            m.d.sync += [is_open[bank].eq(0), act_ready[bank].eq(now + t.t_rp)]

        # A frame's start re-phases the refresh: none until its first request is taken.
        armed = Signal()
        refresh_due = ~armed & (now >= due)
        any_open = Signal()
        all_closable = Signal()
        all_ready = Signal()
        m.d.comb += [
            any_open.eq(sum(is_open[q] for q in range(K)) != 0),
            all_closable.eq(sum(~is_open[q] | may_precharge(q) for q in range(K)) == K),
            all_ready.eq(sum(now >= act_ready[q] for q in range(K)) == K),
        ]
        read_a = Signal()
        with m.If(~self.ready):
            pass
        with m.Elif(refresh_due & ~valid[0] & ~valid[1]):
            with m.If(any_open):
                with m.If(all_closable):
                    m.d.comb += [cmd.eq(PRECHARGE), addr.eq(1 << 10), self.cmd_precharge.eq(1)]
                    for q in range(K):
                        with m.If(is_open[q]):
                            m.d.sync += [is_open[q].eq(0), act_ready[q].eq(now + t.t_rp)]
            with m.Elif(all_ready):
                m.d.comb += [cmd.eq(REFRESH), self.cmd_refresh.eq(1)]
                m.d.sync += due.eq(due + t.t_refi)
                for q in range(K):
                    m.d.sync += act_ready[q].eq(now + t.t_rfc)
        with m.Elif(valid[0] & hit_a & (now >= act_at[a.bank] + t.t_rcd) & (now >= prev_read + BC)):
            m.d.comb += [
                cmd.eq(READ),
                ba.eq(a.bank),
                addr.eq(a.col),
                self.cmd_read.eq(1),
                read_a.eq(1),
            ]
            m.d.sync += [read_at[a.bank].eq(now), prev_read.eq(now)]
        with m.Elif(valid[0] & ~hit_a & is_open[a.bank] & may_precharge(a.bank)):
            precharge(a.bank)
        with m.Elif(valid[0] & ~is_open[a.bank] & may_activate(a.bank)):
            activate(a.bank, a.row)
        with m.Elif(
            valid[1] & (b.bank != a.bank) & ~hit_b & is_open[b.bank] & may_precharge(b.bank)
        ):
            precharge(b.bank)
        with m.Elif(
            valid[1] & (b.bank != a.bank) & hit_a & ~is_open[b.bank] & may_activate(b.bank)
        ):
            activate(b.bank, b.row)
        # The queue: the head leaves on its READ; a request enters the free slot unless a
        # refresh is due by the clock it would enter.
        room = ~valid[1] | read_a
        m.d.comb += self.req.ready.eq(self.ready & room & (armed | (now + 1 < due)))
        take = self.req.valid & self.req.ready
        m.d.comb += self.admit.eq(take)
        with m.If(self.restart):
            m.d.sync += armed.eq(1)
        with m.Elif(armed & take):  # in the queue from now + 1: the frame's refresh clock 0
            m.d.sync += armed.eq(0)
            if t.t_refi > 0:
                m.d.sync += due.eq(now + 1 + t.t_refi)
        with m.If(read_a):
            m.d.sync += [slot[0].eq(slot[1]), valid[0].eq(valid[1]), valid[1].eq(0)]
            with m.If(take):
                with m.If(valid[1]):
                    m.d.sync += [slot[1].eq(self.req.payload), valid[1].eq(1)]
                with m.Else():
                    m.d.sync += [slot[0].eq(self.req.payload), valid[0].eq(1)]
        with m.Elif(take):
            with m.If(valid[0]):
                m.d.sync += [slot[1].eq(self.req.payload), valid[1].eq(1)]
            with m.Else():
                m.d.sync += [slot[0].eq(self.req.payload), valid[0].eq(1)]

    def _capture(self, m):
        """Read words sampled ``1 + cas_latency`` clocks after the READ's decision."""
        t = self.t
        chain = [self.cmd_read]
        for k in range(1 + t.cas_latency):
            nxt = Signal(name=f"read_delay{k}")
            m.d.sync += nxt.eq(chain[-1])
            chain.append(nxt)
        beat = Signal(range(t.burst_length + 1))
        with m.If(chain[-1]):
            m.d.sync += beat.eq(t.burst_length - 1)
        with m.Elif(beat != 0):
            m.d.sync += beat.eq(beat - 1)
        capturing = chain[-1] | (beat != 0)
        m.d.sync += [
            self.rdata_valid.eq(capturing),
            self.rdata_word.eq(self.dq_in),
            self.rdata_last.eq(capturing & (beat == 1) | (chain[-1] & (t.burst_length == 1))),
        ]
