"""A Verilog testbench wrapper of the RTL top whose ROM feeds the ``load`` port, so the
host's table writes run at the simulator's own speed instead of one cocotb await each.

# Ref: shared/docs/toolchain.md ("Python work per cycle dominates ... let a small HDL-side
#      FIFO/memory feed the unit").

``cube4_bench`` has the top's ports except ``load__*`` plus ``preload`` (pulse) and
``preloaded`` (high once every word went in).  The ROM is filled by ``$readmemh`` from the
file named by the ``+loads=FILE`` plusarg; ``+nloads=N`` words are written, one per clock
in file order, exactly what the cocotb driver would have written.  It is testbench code
(not part of the hardware: ``hwsim rtl build top`` exports the top alone).
"""

from __future__ import annotations

from amaranth.hdl import Value

from rtl.export import ports_of

__all__ = ["bench_verilog", "ROM_WORDS"]

#: Largest number of load words (the 16^3 top: volume, LUT, correction, rays, slices).
ROM_WORDS = 16384


def bench_verilog(top, name: str = "cube4_top") -> str:
    """The wrapper module ``cube4_bench`` around module ``name`` (the top's export)."""
    ports = {n: (len(Value.cast(v)), d.value) for n, (v, d) in ports_of(top).items()}
    width = ports["load__payload"][0]
    decl, conn = ["  input clk;", "  input rst;"], [".clk(clk)", ".rst(rst)"]
    names = ["clk", "rst", "preload", "preloaded"]
    for port, (bits, direction) in ports.items():
        if port.startswith("load__"):
            continue
        vec = f"[{bits - 1}:0] " if bits > 1 else ""
        kind = "input" if direction == "input" else "output"
        decl.append(f"  {kind} {vec}{port};")
        conn.append(f".{port}({port})")
        names.append(port)
    conn += [".load__valid(load_valid)", ".load__payload(load_payload)"]
    body = "\n".join(decl)
    return f"""module cube4_bench({", ".join(names)});
{body}
  input preload;
  output reg preloaded;
  reg [{width - 1}:0] rom [0:{ROM_WORDS - 1}];
  reg [1023:0] loads;
  integer nloads;
  reg [31:0] index;
  reg running;
  wire load_valid = running;
  wire [{width - 1}:0] load_payload = rom[index];
  initial begin
    preloaded = 0;
    running = 0;
    index = 0;
    nloads = 0;
    if ($value$plusargs("loads=%s", loads)) $readmemh(loads, rom);
    if (!$value$plusargs("nloads=%d", nloads)) nloads = 0;
  end
  always @(posedge clk) begin
    if (preload && !running) begin
      running <= (nloads != 0);
      preloaded <= (nloads == 0);
      index <= 0;
    end else if (running) begin
      if (index == nloads - 1) begin
        running <= 0;
        preloaded <= 1;
      end
      index <= index + 1;
    end
  end
  {name} dut({", ".join(conn)});
endmodule
"""
