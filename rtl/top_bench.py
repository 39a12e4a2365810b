"""The testbench around the RTL top: it runs a whole frame with no Python per clock.

# Ref: shared/docs/toolchain.md ("Whole-frame RTL runs without Python per clock": preload
#      memories from files, await ``done``, read the image back in bulk).

``cube4_bench`` (Verilog) holds what is outside the chip and what a host would do:

* the **voxel memory**: ``P`` modules in one array of ``P B``-bit words (module ``k`` in
  bits ``k B``), filled by ``$readmemh`` from ``+volume=FILE``; each module's voxel is
  read one clock after the top presents its address (``vmem_en`` low holds it);
* the **host's writes**: the frame registers from ``+r_<name>=HEX`` plusargs, and a ROM
  filled from ``+loads=FILE`` that feeds the top's ``load`` port, ``+nloads=N`` words,
  one per clock;
* the **frame**: after the loads it pulses ``start``, takes every pixel the top offers
  (refusing one clock in ``+stall_every=N`` when ``N > 0``, to exercise back-pressure),
  writes each accepted ``pixel__payload`` as a hex line to ``+pixels=FILE`` and raises
  ``finished`` when the top says ``done``.

Around it only a clock, a reset and one ``go``: a C++ main for Verilator
(:func:`verilator_main`: no VPI, so Verilator optimises the whole model) and a Verilog
top level for Icarus (:func:`icarus_testbench`).  Both print the counters as one JSON
line.  ``clocks`` counts the bench's clocks from ``go`` (loads and frame).  This is
testbench code: ``hwsim rtl build top`` exports the top alone.  The host side it shares
with the vg500 bench (registers, sequencer, C++ clock loop) is :mod:`rtl.bench_host`'s.
"""

from __future__ import annotations

from amaranth.hdl import Value

from rtl.bench_host import host_connections, host_sequencer, register_lines, verilator_main_text
from rtl.export import ports_of
from rtl.top_layouts import load_words_bound

__all__ = ["bench_verilog", "icarus_testbench", "register_ports", "verilator_main"]

#: The frame state's event lines (``+events=FILE``): period starts, frozen clocks, pixels.
_EVENTS = r"""          if (efd != 0) begin
            if (period_start) $fwrite(efd, "S %0d\n", frame_clock);
            if (frozen) $fwrite(efd, "F %0d\n", frame_clock);
            if (pixel_valid && pixel_ready) $fwrite(efd, "P %0d %h\n", frame_clock, pixel_payload);
          end
"""

#: Top ports the bench drives or reads itself (everything else is a frame register).
_BENCH_OWNED = {
    "frame_clock",
    "frozen",
    "period_start",
    "load__valid",
    "load__payload",
    "vmem_addr",
    "vmem_en",
    "vmem_data",
    "start",
    "pixel__valid",
    "pixel__ready",
    "pixel__payload",
    "busy",
    "done",
}


def register_ports(top) -> dict[str, int]:
    """The top's frame registers (inputs the host sets once per frame): name -> bits."""
    return {
        name: len(Value.cast(value))
        for name, (value, direction) in ports_of(top).items()
        if direction.value == "input" and name not in _BENCH_OWNED
    }


def bench_verilog(top, name: str = "cube4_top") -> str:
    """The testbench module ``cube4_bench`` around module ``name`` (the top's export)."""
    geo, dp = top.geo, top.dp
    P, B, A = geo.pipelines, dp.voxel_bits, geo.module_addr_bits
    ports = {n: len(Value.cast(v)) for n, (v, _) in ports_of(top).items()}
    load_bits, pixel_bits = ports["load__payload"], ports["pixel__payload"]
    rom_words = load_words_bound(geo, dp)
    registers = register_ports(top)
    decl = [
        "  input clk;",
        "  input rst;",
        "  input go;",
        "  output reg finished;",
        "  output reg [31:0] clocks;",
        "  output [31:0] cycles;",
        "  output [31:0] samples;",
        "  output [31:0] stall_cycles;",
    ]
    names = ["clk", "rst", "go", "finished", "clocks", "cycles", "samples", "stall_cycles"]
    reg_decl, plusargs = register_lines(registers)
    decl += reg_decl
    memory = (".vmem_addr(vmem_addr)", ".vmem_en(vmem_en)", ".vmem_data(vmem_data)")
    conn = host_connections(registers, memory)
    conn += [".frame_clock(frame_clock)", ".frozen(frozen)", ".period_start(period_start)"]
    sequencer = host_sequencer(
        3,
        "        2: begin\n          state <= 3;\n          tick <= 0;\n        end",
        each_clock="          tick <= tick + 1;\n",
        after_pixel=_EVENTS,
        on_done="            if (efd != 0) $fclose(efd);\n",
    )
    reads = "\n".join(
        f"      if (vmem_addr[{k * A + A - 1}:{k * A}] < {geo.module_words})\n"
        f"        vmem_data[{k * B + B - 1}:{k * B}] <= "
        f"vmem[vmem_addr[{k * A + A - 1}:{k * A}]][{k * B + B - 1}:{k * B}];"
        for k in range(P)
    )
    body = "\n".join(decl)
    return f"""module cube4_bench({", ".join(names)});
{body}
  // Outside the chip: the voxel memory and the host's table writes.
  reg [{P * B - 1}:0] vmem [0:{geo.module_words - 1}];
  reg [{load_bits - 1}:0] rom [0:{rom_words - 1}];
  reg [8*512-1:0] path;
  integer nloads, stall_every, fd, efd;
  wire [31:0] frame_clock;
  wire frozen, period_start;
  reg [2:0] state;  // 0 idle, 1 loading, 2 start, 3 frame, 4 finished
  reg [31:0] index, tick;
  wire load_valid = state == 1;
  wire [{load_bits - 1}:0] load_payload = rom[index];
  wire start = state == 2;
  wire pixel_ready = (stall_every == 0) || (tick % stall_every != 0);
  wire pixel_valid, busy, done, vmem_en;
  wire [{pixel_bits - 1}:0] pixel_payload;
  wire [{P * A - 1}:0] vmem_addr;
  reg [{P * B - 1}:0] vmem_data;
  initial begin
    state = 0;
    finished = 0;
    clocks = 0;
    index = 0;
    tick = 0;
    vmem_data = 0;
    fd = 0;
    efd = 0;
    if ($value$plusargs("volume=%s", path)) $readmemh(path, vmem);
    if ($value$plusargs("loads=%s", path)) $readmemh(path, rom);
    if (!$value$plusargs("nloads=%d", nloads)) nloads = 0;
    if (!$value$plusargs("stall_every=%d", stall_every)) stall_every = 0;
    if ($value$plusargs("pixels=%s", path)) fd = $fopen(path, "w");
    if ($value$plusargs("events=%s", path)) efd = $fopen(path, "w");
{plusargs}
  end
  always @(posedge clk) begin
    if (vmem_en) begin
{reads}
    end
  end
{sequencer}
  {name} dut({", ".join(conn)});
endmodule
"""


def icarus_testbench() -> str:
    """``cube4_tb``: Icarus's top level around ``cube4_bench`` (a 10 ns clock, reset, one
    ``go``; prints the counters as one ``HWSIM {...}`` JSON line when ``finished``, or
    after ``+limit=N`` clocks)."""
    return r"""`timescale 1ns/1ps
module cube4_tb;
  reg clk = 0, rst = 1, go = 0;
  wire finished;
  wire [31:0] clocks, cycles, samples, stall_cycles;
  integer limit, n;
  reg [8*128-1:0] tail;
  always #5 clk = ~clk;
  cube4_bench bench(.clk(clk), .rst(rst), .go(go), .finished(finished), .clocks(clocks),
                    .cycles(cycles), .samples(samples), .stall_cycles(stall_cycles));
  initial begin
    if (!$value$plusargs("limit=%d", limit)) limit = 100000000;
    repeat (2) @(posedge clk);
    rst <= 0;  // nonblocking: the bench samples the old value at this edge, no race
    go <= 1;
    @(posedge clk);
    go <= 0;
    n = 0;
    while (!finished && n < limit) begin
      @(posedge clk);
      n = n + 1;
    end
    $sformat(tail, "\"stall_cycles\": %0d, \"clocks\": %0d}", stall_cycles, clocks);
    $display("HWSIM {\"finished\": %0d, \"cycles\": %0d, \"samples\": %0d, %s",
             finished, cycles, samples, tail);
    $finish;
  end
endmodule
"""


def verilator_main() -> str:
    """The C++ main of the Verilator model: the clock, reset and ``go`` in C++, the frame
    in the model, the counters and the simulated seconds printed as one ``HWSIM {...}``
    JSON line (``+limit=N`` clocks at most); every 16384 clocks, the samples taken so far
    as a ``HWSIM_PROGRESS <samples>`` line (the rtl rung's progress)."""
    return verilator_main_text(
        "cube4_bench",
        """  bench->clk = 0;
  bench->rst = 1;
  bench->go = 0;
  bench->eval();
  tick();
  tick();
  bench->rst = 0;
  bench->go = 1;
  tick();
  bench->go = 0;
""",
    )
