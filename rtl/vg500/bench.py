"""The testbench around the vg500 top: four SDR SDRAM devices and their datasheet
checkers on the top's pins, the host's writes, the frame; no Python per clock.

# Ref: rtl/top_bench.py (the Cube-4 bench this follows); rtl/sdram/sdr_sdram.v and
#      sdram_checker.v (the devices and checkers, rtl/sdram/sdr_sdram.v (the sdram_pins contract)).

``vg500_bench`` (Verilog) holds what is outside the chip: ``sdr_sdram`` devices
``dev0..3`` (``ROWS`` rows per bank: those the size class needs), each loaded by its
``load_memh`` task from ``+sdram<k>=FILE``; a ``sdram_checker`` per device on the same
pins (violations, activates, reads, precharges, refreshes summed over the four); the
host's writes (registers from ``+r_<name>=HEX``, the ``load`` ROM from ``+loads=FILE``);
after the loads and the devices' power-up it pulses ``start``, takes every pixel into
``+pixels=FILE`` and raises ``finished`` at ``done``.  Its only input is the clock: the
reset (two clocks) and the ``go`` pulse come from a power-on counter inside it, so no
logic depends on a port the C++ main writes (Verilator re-evaluates such logic on every
``eval``: with ``rst`` and ``go`` as ports that was nearly half the simulation's time).
The C++ main for Verilator (:func:`vg500_main`) prints the Cube-4 bench's ``HWSIM {...}``
line and a ``HWSIM_VG500 {...}`` line with the memory's counters, among them
``frame_refreshes``: the checkers' refreshes from the frame's start to its last READ (what
the cycle rung's scheduler counts: no refresh before the frame's first request or after
its last; the checkers' ``refreshes`` count from the devices' power-up, the host's loads
and the frame's tail included).
"""

from __future__ import annotations

from amaranth.hdl import Value

from rtl.bench_host import host_connections, host_sequencer, register_lines, verilator_main_text
from rtl.export import ports_of
from rtl.top_bench import register_ports
from rtl.top_layouts import load_words_bound
from rtl.vg500.sdram_ctrl import T_MRD, SdramTiming
from rtl.vg500.top import PINS_OUT

__all__ = ["vg500_bench_verilog", "vg500_main", "COUNTERS"]

#: The checkers' counters the bench sums over the four devices.
COUNTERS = ("violations", "activates", "reads", "precharges", "refreshes")
_OWNED = {f"sdram{k}_{p}" for k in range(4) for p in (*PINS_OUT, "dq_in")}
_OWNED |= {"memory_ready", "hold_cycles", "bursts"}


#: The sequencer's states between the loads and the frame: wait for the devices'
#: power-up (``memory_ready``), then pulse ``start``.
_BEFORE_FRAME = "        2: if (memory_ready) state <= 3;\n        3: state <= 4;"


def _timing_params(t: SdramTiming) -> str:
    return (
        f".CL({t.cas_latency}), .BL({t.burst_length}), .T_RCD({t.t_rcd}), .T_RP({t.t_rp}), "
        f".T_RAS({t.t_ras}), .T_RC({t.t_rc}), .T_RRD({t.t_rrd}), .T_RFC({t.t_rfc}), "
        f".T_REFI({t.t_refi})"
    )


def vg500_bench_verilog(top, rows: int, *, strict: bool = False) -> str:
    """Module ``vg500_bench`` around module ``vg500_top`` (the top's export)."""
    geo, dp, t = top.geo, top.dp, top.timing
    ports = {n: len(Value.cast(v)) for n, (v, _) in ports_of(top).items()}
    load_bits, pixel_bits = ports["load__payload"], ports["pixel__payload"]
    registers = {k: v for k, v in register_ports(top).items() if k not in _OWNED}
    decl, plusargs = register_lines(registers)
    conn = host_connections(registers)
    conn += [".hold_cycles(hold_cycles)", ".bursts(bursts)", ".memory_ready(memory_ready)"]
    devices = []
    for k in range(4):
        conn += [f".sdram{k}_{p}(s{k}_{p})" for p in (*PINS_OUT, "dq_in")]
        pins = (
            f".clk(clk), .cke(s{k}_cke), .cs_n(s{k}_cs_n), .ras_n(s{k}_ras_n), "
            f".cas_n(s{k}_cas_n), .we_n(s{k}_we_n), .ba(s{k}_ba), .a(s{k}_a)"
        )
        devices.append(
            f"""  wire s{k}_cke, s{k}_cs_n, s{k}_ras_n, s{k}_cas_n, s{k}_we_n, s{k}_dq_oe;
  wire [1:0] s{k}_ba, s{k}_dqm;
  wire [12:0] s{k}_a;
  wire [15:0] s{k}_dq_out, s{k}_dq_in;
  wire s{k}_dq_valid;
  wire [31:0] s{k}_mode_errors, s{k}_refresh_count, c{k}_writes, c{k}_auto, c{k}_cycle;
  wire c{k}_ready;
  wire [31:0] {", ".join(f"c{k}_{c}" for c in COUNTERS)};
  sdr_sdram #({_timing_params(t)}, .BANKS({t.banks}), .ROWS({rows}), .COLS({t.columns})) dev{k} (
      {pins}, .dqm(s{k}_dqm), .dq_out(s{k}_dq_out), .dq_oe(s{k}_dq_oe), .dq_in(s{k}_dq_in),
      .dq_valid(s{k}_dq_valid), .mode_errors(s{k}_mode_errors),
      .refresh_count(s{k}_refresh_count));
  sdram_checker #({_timing_params(t)}, .T_MRD({T_MRD}), .BANKS({t.banks}),
      .STRICT({int(strict)})) chk{k} (
      {pins}, {", ".join(f".{c}(c{k}_{c})" for c in COUNTERS)}, .writes(c{k}_writes),
      .auto_precharges(c{k}_auto), .cycle(c{k}_cycle), .ready(c{k}_ready));"""
        )
    sums = "\n".join(
        f"  assign {c} = {' + '.join(f'c{k}_{c}' for k in range(4))};" for c in COUNTERS
    )
    loads = "\n".join(
        f'    if ($value$plusargs("sdram{k}=%s", path)) dev{k}.load_memh(path);' for k in range(4)
    )
    body = "\n".join(decl)
    names = ["clk", "finished", "clocks", "cycles", "samples", "stall_cycles"]
    names += ["hold_cycles", "bursts", "frame_refreshes", *COUNTERS]
    return f"""module vg500_bench({", ".join(names)});
  input clk;
  output reg finished;
  output reg [31:0] clocks;
  output [31:0] cycles, samples, stall_cycles, hold_cycles, bursts;
  output [31:0] {", ".join(COUNTERS)};
  output [31:0] frame_refreshes;
{body}
{chr(10).join(devices)}
{sums}
  reg [{load_bits - 1}:0] rom [0:{load_words_bound(geo, dp) - 1}];
  reg [8*512-1:0] path;
  integer nloads, fd;
  reg [31:0] refreshes_at_start, refreshes_at_read, reads_seen;
  assign frame_refreshes = refreshes_at_read - refreshes_at_start;
  always @(posedge clk) begin
    if (state == 3) begin
      refreshes_at_start <= refreshes;
      refreshes_at_read <= refreshes;
      reads_seen <= reads;
    end else if (state == 4 && reads != reads_seen) begin
      reads_seen <= reads;
      refreshes_at_read <= refreshes;
    end
  end
  reg [1:0] power_on;  // clocks 0, 1: reset; clock 2: go
  wire rst = power_on < 2;
  wire go = power_on == 2;
  always @(posedge clk) if (power_on != 3) power_on <= power_on + 1;
  reg [2:0] state;  // 0 idle, 1 loading, 2 wait for the memory, 3 start, 4 frame, 5 done
  reg [31:0] index;
  wire load_valid = state == 1;
  wire [{load_bits - 1}:0] load_payload = rom[index];
  wire start = state == 3;
  wire pixel_ready = 1'b1;
  wire pixel_valid, busy, done, memory_ready;
  wire [{pixel_bits - 1}:0] pixel_payload;
  initial begin
    refreshes_at_start = 0;
    refreshes_at_read = 0;
    reads_seen = 0;
    power_on = 0;
    state = 0;
    finished = 0;
    clocks = 0;
    index = 0;
    fd = 0;
    if ($value$plusargs("loads=%s", path)) $readmemh(path, rom);
    if (!$value$plusargs("nloads=%d", nloads)) nloads = 0;
    if ($value$plusargs("pixels=%s", path)) fd = $fopen(path, "w");
{loads}
{plusargs}
  end
{host_sequencer(4, _BEFORE_FRAME)}
  vg500_top dut({", ".join(conn)});
endmodule
"""


def vg500_main() -> str:
    """The C++ main of ``vg500_bench``: the clock in C++, nothing else driven (the bench
    resets and starts itself); the Cube-4 bench's ``HWSIM {...}`` line (``+limit=N``
    clocks at most, ``seconds``: the clock loop after the power-on clocks), a
    ``HWSIM_PROGRESS <samples>`` line every 16384 clocks and one ``HWSIM_VG500 {...}``
    line with the memory's counters."""
    names = ("hold_cycles", "bursts", "frame_refreshes", *COUNTERS)
    extra = ", ".join(f'\\"{c}\\": %u' for c in names)
    args = ", ".join(f"bench->{c}" for c in names)
    after = f'  std::printf("HWSIM_VG500 {{{extra}}}\\n", {args});\n'
    reset = "  bench->clk = 0;\n  bench->eval();\n"
    reset += "  for (int k = 0; k < 3; ++k) tick();  // the bench's reset and go\n"
    return verilator_main_text("vg500_bench", reset, after)
