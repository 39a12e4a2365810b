"""A stand-in SDR SDRAM for the Amaranth simulator: the device's data and a timing checker
written from the datasheet rules (not from hwsim.memory), used until rtl/sdram's Verilog
device and checker replace it in the Verilator testbench.

# Ref: any PC100/PC133 SDR SDRAM datasheet: command truth table (cs_n, ras_n, cas_n, we_n),
#      tRCD, tRP, tRAS, tRC, tRRD, tRFC, burst length, CAS latency; rtl/sdram/sdr_sdram.v
#      (the sdram_pins contract).
"""

from __future__ import annotations

from dataclasses import dataclass, field

NEVER = -(1 << 30)
NAMES = {
    0b0111: "NOP",
    0b0011: "ACTIVATE",
    0b0101: "READ",
    0b0100: "WRITE",
    0b0010: "PRECHARGE",
    0b0001: "REFRESH",
    0b0000: "LOAD_MODE",
}


@dataclass
class StandInSdram:
    """Pins in, read data out; every command checked at the clock it is sampled."""

    t: object  # rtl.vg500.sdram_ctrl.SdramTiming
    words: dict  # (bank, row, col) -> word
    mode: int | None = None
    violations: list = field(default_factory=list)
    counts: dict = field(default_factory=lambda: dict.fromkeys(NAMES.values(), 0))
    log: list = field(default_factory=list)

    def __post_init__(self):
        K = self.t.banks
        self.open = [None] * K
        self.act_at = [NEVER] * K
        self.pre_at = [NEVER] * K
        self.read_at = [NEVER] * K
        self.last_act = self.last_ref = self.last_read = NEVER
        self.refreshes_before_mode = 0
        self.out: dict[int, int] = {}  # clock -> word presented on dq_in

    def _bad(self, clock, rule, bank, since):
        self.violations.append(f"clock {clock}: {rule} (bank {bank}, since clock {since})")

    def sample(self, clock: int, cs_n, ras_n, cas_n, we_n, ba, a) -> str:
        """The command on the pins at the edge ending ``clock``."""
        if cs_n:
            return "DESELECT"
        name = NAMES[(ras_n << 2) | (cas_n << 1) | we_n]
        self.counts[name] += 1
        t = self.t
        if name == "NOP":
            return name
        self.log.append((clock, name, ba, a))
        if name == "LOAD_MODE":
            self.mode = a
            if any(o is not None for o in self.open) or self.refreshes_before_mode < 2:
                self._bad(clock, "LOAD MODE before PRECHARGE all and 2 refreshes", -1, clock)
        elif name == "REFRESH":
            if any(o is not None for o in self.open):
                self._bad(clock, "REFRESH with a bank open", -1, clock)
            for q in range(t.banks):
                if clock < self.pre_at[q] + t.t_rp:
                    self._bad(clock, "tRP before REFRESH", q, self.pre_at[q])
            if clock < self.last_ref + t.t_rfc:
                self._bad(clock, "tRFC", -1, self.last_ref)
            self.last_ref = clock
            if self.mode is None:
                self.refreshes_before_mode += 1
        elif name == "PRECHARGE":
            banks = range(t.banks) if a & (1 << 10) else [ba]
            for q in banks:
                if self.open[q] is not None:
                    if clock < self.act_at[q] + t.t_ras:
                        self._bad(clock, "tRAS", q, self.act_at[q])
                    if clock < self.read_at[q] + t.burst_length:
                        self._bad(clock, "PRECHARGE cuts a burst", q, self.read_at[q])
                    self.pre_at[q] = clock
                self.open[q] = None
        elif name == "ACTIVATE":
            self._mode_set(clock)
            if self.open[ba] is not None:
                self._bad(clock, "ACTIVATE of an open bank", ba, self.act_at[ba])
            for lim, since, rule in (
                (t.t_rp, self.pre_at[ba], "tRP"),
                (t.t_rc, self.act_at[ba], "tRC"),
                (t.t_rrd, self.last_act, "tRRD"),
                (t.t_rfc, self.last_ref, "tRFC"),
            ):
                if clock < since + lim:
                    self._bad(clock, rule, ba, since)
            self.open[ba] = a
            self.act_at[ba] = self.last_act = clock
        elif name == "READ":
            self._mode_set(clock)
            if self.open[ba] is None:
                self._bad(clock, "READ of a closed bank", ba, self.pre_at[ba])
            elif clock < self.act_at[ba] + t.t_rcd:
                self._bad(clock, "tRCD", ba, self.act_at[ba])
            if clock < self.last_read + t.burst_length:
                self._bad(clock, "burst overlap on dq", ba, self.last_read)
            self.read_at[ba] = self.last_read = clock
            col = a & 0x1FF
            for j in range(t.burst_length):
                self.out[clock + t.cas_latency + j] = self.words.get(
                    (ba, self.open[ba] or 0, col + j), 0
                )
        else:
            self._bad(clock, f"unexpected {name}", ba, clock)
        return name

    def _mode_set(self, clock):
        if self.mode is None:
            self._bad(clock, "command before LOAD MODE", -1, clock)

    def dq(self, clock: int) -> int:
        """The word on dq_in during ``clock``."""
        return self.out.pop(clock, 0)
