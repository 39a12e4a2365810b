"""An SDR SDRAM device's data path in Amaranth, for runs of the vg500 top on Amaranth's
simulator (the Verilator and Icarus benches attach ``rtl/sdram/sdr_sdram.v`` and its
``sdram_checker`` instead).

# Ref: any PC100/PC133 SDR SDRAM datasheet (ACTIVATE opens a row per bank; READ bursts
#      ``burst_length`` sequential words; beat ``i`` sampled ``CL + i`` edges after the
#      edge that sampled the READ); rtl/sdram/sdr_sdram.v (the sdram_pins contract).

Storage ``words[(bank rows + row) columns + column]`` (``rows``: only those the volume
uses).  No timing is checked here (the checker's job); a READ of a row never opened reads
row 0.
"""

from __future__ import annotations

from amaranth import Elaboratable, Module, Mux, Signal, unsigned
from amaranth.lib.memory import Memory

__all__ = ["SdramDevice"]


class SdramDevice(Elaboratable):
    """One module's device: the pin signals of ``ctl`` (an SdramController or the top's
    ``sdram<m>_*`` ports) as ``pins``, a dict of signals by pin name."""

    def __init__(self, pins: dict, words: list[int], *, banks=4, rows=1, columns=512, cl=2, bl=8):
        self.pins, self.words = pins, words
        self.banks, self.rows, self.columns, self.cl, self.bl = banks, rows, columns, cl, bl

    def elaborate(self, platform):
        m = Module()
        p = self.pins
        depth = self.banks * self.rows * self.columns
        m.submodules.mem = mem = Memory(shape=unsigned(16), depth=depth, init=self.words)
        port = mem.read_port()
        cmd = Signal(4)
        m.d.comb += cmd.eq((p["cs_n"] << 3) | (p["ras_n"] << 2) | (p["cas_n"] << 1) | p["we_n"])
        open_row = [Signal(13, name=f"open_row{b}") for b in range(self.banks)]
        for b in range(self.banks):
            with m.If((cmd == 0b0011) & (p["ba"] == b)):
                m.d.sync += open_row[b].eq(p["a"])
        row = Signal(13)
        with m.Switch(p["ba"]):
            for b in range(self.banks):
                with m.Case(b):
                    m.d.comb += row.eq(open_row[b])
        # READ seen in clock n: beat i on dq_in in clock n + CL + i; the memory read is one
        # clock, so beat i's address is presented in clock n + CL - 1 + i.
        base = Signal(range(depth + self.columns))
        m.d.comb += base.eq((p["ba"] * self.rows + row) * self.columns + (p["a"][:9]))
        delay = [(Signal(name="rd0"), Signal(range(depth + self.columns), name="ad0"))]
        m.d.comb += [delay[0][0].eq(cmd == 0b0101), delay[0][1].eq(base)]
        for k in range(1, self.cl):
            v, a = Signal(name=f"rd{k}"), Signal(range(depth + self.columns), name=f"ad{k}")
            m.d.sync += [v.eq(delay[-1][0]), a.eq(delay[-1][1])]
            delay.append((v, a))
        left = Signal(range(self.bl + 1))
        addr = Signal(range(depth + self.columns))
        start, start_addr = delay[-1]
        with m.If(start):
            m.d.sync += [left.eq(self.bl - 1), addr.eq(start_addr + 1)]
        with m.Elif(left != 0):
            m.d.sync += [left.eq(left - 1), addr.eq(addr + 1)]
        m.d.comb += port.addr.eq(Mux(start, start_addr, addr))
        m.d.comb += p["dq_in"].eq(port.data)
        return m
