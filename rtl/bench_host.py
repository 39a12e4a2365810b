"""What the RTL tops' testbenches share: the host around ``cube4_bench``
(:mod:`rtl.top_bench`) and ``vg500_bench`` (:mod:`rtl.vg500.bench`).

# Ref: shared/docs/toolchain.md ("Whole-frame RTL runs without Python per clock": preload
#      memories from files, await ``done``, read the image back in bulk).

* the **frame registers**: declared, each set from a ``+r_<name>=HEX`` plusarg (0
  without one) and connected to the top's input of the same name
  (:func:`register_lines`, :func:`host_connections`);
* the **host's port connections** to the top: clock, reset, registers, the ``load``
  stream, ``start``, the ``pixel`` stream and the frame's counters;
* the **host sequencer** (:func:`host_sequencer`): idle until ``go``, the ``load`` ROM
  one word a clock, the bench's own states before the frame, the frame (every accepted
  pixel written to ``+pixels=FILE``), finished at ``done``;
* the **Verilator C++ main** (:func:`verilator_main_text`): the clock in C++, a
  ``HWSIM_PROGRESS <samples>`` line every 16384 clocks and the counters as one
  ``HWSIM {...}`` JSON line.
"""

from __future__ import annotations

__all__ = ["host_connections", "host_sequencer", "register_lines", "verilator_main_text"]


def register_lines(registers: dict[str, int]) -> tuple[list[str], str]:
    """The frame registers' declarations (``reg [bits-1:0] name;``, one a line) and the
    initial block's lines setting each from ``+r_<name>=HEX`` (0 without one)."""
    decl = [f"  reg {f'[{b - 1}:0] ' if b > 1 else ''}{p};" for p, b in registers.items()]
    plusargs = "\n".join(f'    if (!$value$plusargs("r_{p}=%h", {p})) {p} = 0;' for p in registers)
    return decl, plusargs


def host_connections(registers: dict[str, int], memory: tuple[str, ...] = ()) -> list[str]:
    """The top's ports the host side drives or reads (``.port(net)``): clock, reset, the
    frame registers, ``load``, then ``memory`` (the bench's memory ports, if the memory
    is outside the top), ``start``, ``pixel``, ``busy``, ``done`` and the counters."""
    return [
        ".clk(clk)",
        ".rst(rst)",
        *(f".{p}({p})" for p in registers),
        ".load__valid(load_valid)",
        ".load__payload(load_payload)",
        *memory,
        ".start(start)",
        ".pixel__valid(pixel_valid)",
        ".pixel__ready(pixel_ready)",
        ".pixel__payload(pixel_payload)",
        ".busy(busy)",
        ".done(done)",
        ".cycles(cycles)",
        ".samples(samples)",
        ".stall_cycles(stall_cycles)",
    ]


def host_sequencer(
    frame: int, before: str, *, each_clock: str = "", after_pixel: str = "", on_done: str = ""
) -> str:
    """The bench's sequencer (a Verilog ``always`` block on ``state``): 0 waits for
    ``go`` (to 1 with loads, else 2), 1 presents ROM word ``index`` on ``load`` each
    clock, ``before`` holds the bench's case items for states 2 to ``frame - 1`` (the
    last moves to ``frame``), ``frame`` writes every accepted pixel to ``fd`` until
    ``done``, then ``frame + 1``: ``finished``.  ``clocks`` counts from ``go`` to
    ``done``.  ``each_clock``, ``after_pixel`` and ``on_done``: the frame state's own
    lines (before and after the pixel's, and at ``done``), each ending in a newline."""
    end = frame + 1
    pixel = (
        '          if (pixel_valid && pixel_ready && fd != 0) $fwrite(fd, "%h\\n", pixel_payload);'
    )
    return f"""  always @(posedge clk) begin
    if (rst) begin
      state <= 0;
      finished <= 0;
    end else begin
      if (state != 0 && state != {end}) clocks <= clocks + 1;
      case (state)
        0: if (go) begin
          state <= nloads != 0 ? 1 : 2;
          index <= 0;
          clocks <= 0;
        end
        1: begin
          if (index == nloads - 1) state <= 2;
          index <= index + 1;
        end
{before}
        {frame}: begin
{each_clock}{pixel}
{after_pixel}          if (done) begin
            state <= {end};
            finished <= 1;
            if (fd != 0) $fclose(fd);
{on_done}          end
        end
        default: ;
      endcase
    end
  end"""


_MAIN = r"""#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include "V@BENCH@.h"
#include "verilated.h"

int main(int argc, char** argv) {
  VerilatedContext* ctx = new VerilatedContext;
  ctx->commandArgs(argc, argv);
  V@BENCH@* bench = new V@BENCH@{ctx};
  long long limit = 100000000LL;
  const char* arg = ctx->commandArgsPlusMatch("limit=");
  if (arg && std::strlen(arg) > 7) limit = std::atoll(arg + 7);
  auto tick = [&]() {
    bench->clk = 1;
    bench->eval();
    bench->clk = 0;
    bench->eval();
  };
@RESET@  auto start = std::chrono::steady_clock::now();
  long long n = 0;
  while (!bench->finished && n < limit) {
    tick();
    ++n;
    if ((n & 0x3FFF) == 0) {
      std::printf("HWSIM_PROGRESS %u\n", bench->samples);
      std::fflush(stdout);
    }
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("HWSIM {\"finished\": %d, \"cycles\": %u, \"samples\": %u, "
              "\"stall_cycles\": %u, \"clocks\": %u, \"seconds\": %.6f}\n",
              (int)bench->finished, bench->cycles, bench->samples, bench->stall_cycles,
              bench->clocks, seconds);
@AFTER@  bench->final();
  delete bench;
  delete ctx;
  return 0;
}
"""


def verilator_main_text(bench: str, reset: str, after: str = "") -> str:
    """The C++ main of the Verilator model of module ``bench``: ``reset`` (C++ lines
    ending in a newline: the clocks before the frame's, whose ``seconds`` start after
    them), the clock loop (``+limit=N`` clocks at most, a ``HWSIM_PROGRESS <samples>``
    line every 16384), the ``HWSIM {...}`` counters line, then ``after``."""
    return _MAIN.replace("@BENCH@", bench).replace("@RESET@", reset).replace("@AFTER@", after)
