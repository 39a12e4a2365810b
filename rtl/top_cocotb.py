"""cocotb test module: one frame of the RTL top on Icarus or Verilator (run by
:func:`rtl.rung.run_simulator` through cocotb's Python runner, not collected by pytest).

The toplevel is :mod:`rtl.top_bench`'s wrapper: its ROM (the ``+loads`` hex file) feeds
the host's load words at simulator speed.  The job file (``HWSIM_RTL_JOB``) holds the
frame registers, the load count and the pixel back-pressure pattern; the result file
(``HWSIM_RTL_RESULT``) gets the raw pixel words, the frame's cycles and samples, and the
simulated clocks.
"""

from __future__ import annotations

import json
import os

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge


@cocotb.test()
async def frame(dut):
    """Load, start, collect every pixel until ``done``."""
    with open(os.environ["HWSIM_RTL_JOB"]) as f:
        job = json.load(f)
    Clock(dut.clk, 10, unit="ns", impl="gpi").start()
    dut.rst.value = 1
    dut.start.value = 0
    dut.preload.value = 0
    dut.pixel__ready.value = 1
    for name, value in job["registers"].items():
        getattr(dut, name).value = value
    for _ in range(2):
        await RisingEdge(dut.clk)
    dut.rst.value = 0
    clk = dut.clk
    # The bench's ROM writes the host's words into the load port, one per clock.
    dut.preload.value = 1
    await RisingEdge(clk)
    dut.preload.value = 0
    while not int(dut.preloaded.value):
        await RisingEdge(dut.preloaded)
    await RisingEdge(clk)
    dut.start.value = 1
    await RisingEdge(clk)
    dut.start.value = 0
    stall = int(job["stall_every"])
    p_valid, p_ready, p_payload, done = (
        dut.pixel__valid,
        dut.pixel__ready,
        dut.pixel__payload,
        dut.done,
    )
    pixels, clock, ready = [], 0, 1
    limit = int(job["limit"])
    while True:
        want = 0 if stall and clock % stall == 0 else 1
        if want != ready:
            p_ready.value = ready = want
        await ReadOnly()
        if ready and int(p_valid.value):
            pixels.append(format(p_payload.value.to_unsigned(), "x"))
        if int(done.value):
            break
        await RisingEdge(clk)
        clock += 1
        assert clock < limit, "the RTL top did not finish"
    result = {
        "pixels": pixels,
        "cycles": int(dut.cycles.value),
        "samples": int(dut.samples.value),
        "stall_cycles": int(dut.stall_cycles.value),
        "clocks": clock + int(job["load_count"]) + 4,
    }
    with open(os.environ["HWSIM_RTL_RESULT"], "w") as f:
        json.dump(result, f)
