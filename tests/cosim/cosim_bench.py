"""cocotb test module: one unit's exported Verilog against its model, on Icarus or
Verilator (driven by tests/cosim/test_cosim_units.py through cocotb's Python runner).

Driver -> monitor -> model -> checker: the shared :class:`stream_bench.StreamBench`
drives the input stream and the output ``ready`` each cycle and monitors both
handshakes at ``ReadOnly`` (settled values of the cycle); after every phase of the idle x
backpressure crossing the unit's own model is run on the monitored inputs and the
checker compares every output field bit for bit.  A summary (vectors, cycles, measured
latencies) goes to ``HWSIM_COSIM_SUMMARY`` for the pytest side.
"""

from __future__ import annotations

import json
import os

import cocotb
import numpy as np
from amaranth_bench import check_outputs
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge
from stream_bench import PHASES, StreamBench, pack
from unit_cases import make_case


@cocotb.test()
async def unit_matches_model(dut):
    """Every phase: outputs equal the model's, latency equals the declared one, II = 1."""
    unit = os.environ["HWSIM_COSIM_UNIT"]
    count = int(os.environ["HWSIM_COSIM_COUNT"])
    seed = int(os.environ.get("HWSIM_COSIM_SEED", "1"))
    case = make_case(unit)
    rng = np.random.default_rng(seed)

    Clock(dut.clk, 10, unit="ns").start()
    dut.rst.value = 1
    dut.i__valid.value = 0
    dut.o__ready.value = 0
    for name, value in case.statics.items():
        getattr(dut, name).value = value
    if case.loads:
        dut.load__valid.value = 0
    for _ in range(2):
        await RisingEdge(dut.clk)
    dut.rst.value = 0
    if case.loads:
        dut.load__valid.value = 1
        for word in case.loads:
            dut.load__payload.value = word
            await RisingEdge(dut.clk)
        dut.load__valid.value = 0

    summary = []
    i_valid, i_payload, o_ready = dut.i__valid, dut.i__payload, dut.o__ready
    i_ready, o_valid, o_payload = dut.i__ready, dut.o__valid, dut.o__payload
    for p, (idle, stall) in enumerate(PHASES):
        stim = case.stimulus(rng, count)
        bench = StreamBench(pack(case.in_layout, stim), idle, stall, seed + p)
        limit = 20 * len(bench.words) + 100
        last = (None, None, None)  # write a port only when its value changes (GPI calls cost)
        while not bench.done:
            now = bench.drive()
            if now[0] != last[0]:
                i_valid.value = now[0]
            if now[0] and now[1] != last[1]:
                i_payload.value = now[1]
            if now[2] != last[2]:
                o_ready.value = now[2]
            last = (now[0], now[1] if now[0] else last[1], now[2])
            await ReadOnly()
            ov = int(o_valid.value)
            bench.observe(int(i_ready.value), ov, o_payload.value.to_unsigned() if ov else 0)
            await RisingEdge(dut.clk)
            assert bench.cycle < limit, "unit stopped producing outputs"
        i_valid.value = 0
        o_ready.value = 1
        bench.check(case.latency, idle, stall, case.ii)
        check_outputs(case, stim, bench.outputs)  # model -> checker
        lat = np.array(bench.out_cycles) - np.array(bench.in_cycles)
        summary.append(
            {
                "idle": idle,
                "stall": stall,
                "vectors": len(bench.words),
                "cycles": bench.cycle,
                "latency_min": int(lat.min()),
                "latency_max": int(lat.max()),
            }
        )
    with open(os.environ["HWSIM_COSIM_SUMMARY"], "w") as f:
        json.dump({"unit": unit, "declared_latency": case.latency, "phases": summary}, f)
