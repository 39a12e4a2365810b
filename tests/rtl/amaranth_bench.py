"""Run a :class:`unit_cases.UnitCase` on Amaranth's own simulator: load the tables, set the
static inputs, then stream every phase of the idle x backpressure crossing through the
unit with the shared driver/monitor, and check each phase against the model."""

from __future__ import annotations

import numpy as np
from amaranth.hdl import Value
from amaranth.sim import Simulator
from stream_bench import PHASES, StreamBench, pack, unpack

__all__ = ["run_case"]


def run_case(case, count: int, seed: int = 1, phases=PHASES) -> dict:
    """Stream ``count`` random vectors plus the extremes per phase; returns per-phase
    ``{"vectors", "cycles"}`` after asserting bit-exact outputs, latency and II."""
    dut = case.build()
    rng = np.random.default_rng(seed)
    plans = []
    for p, (idle, stall) in enumerate(phases):
        stim = case.stimulus(rng, count)
        plans.append(
            (idle, stall, stim, StreamBench(pack(case.in_layout, stim), idle, stall, seed + p))
        )
    i_payload, o_payload = Value.cast(dut.i.payload), Value.cast(dut.o.payload)

    async def testbench(ctx):
        for name, value in case.statics.items():
            ctx.set(Value.cast(getattr(dut, name)), value)
        if case.loads:
            ctx.set(dut.load.valid, 1)
            load_payload = Value.cast(dut.load.payload)
            for word in case.loads:
                ctx.set(load_payload, word)
                await ctx.tick()
            ctx.set(dut.load.valid, 0)
        for *_, bench in plans:
            while not bench.done:
                valid, word, ready = bench.drive()
                ctx.set(dut.i.valid, valid)
                ctx.set(i_payload, word)
                ctx.set(dut.o.ready, ready)
                bench.observe(ctx.get(dut.i.ready), ctx.get(dut.o.valid), ctx.get(o_payload))
                await ctx.tick()
                if bench.cycle > 20 * len(bench.words) + 100:
                    raise AssertionError("unit stopped producing outputs")
            ctx.set(dut.i.valid, 0)
            ctx.set(dut.o.ready, 1)
            for _ in range(case.latency + 1):  # drain: nothing may come out uninvited
                assert not ctx.get(dut.o.valid)
                await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    report = {}
    for idle, stall, stim, bench in plans:
        bench.check(case.latency, idle, stall, case.ii)
        check_outputs(case, stim, bench.outputs)
        report[(idle, stall)] = {"vectors": len(bench.words), "cycles": bench.cycle}
    return report


def check_outputs(case, stim: dict, words: list[int]) -> None:
    """Model outputs of ``stim`` equal the monitored ``words`` field by field, bit for bit."""
    expected = case.model(stim)
    got = unpack(case.out_layout, words)
    assert set(got) == set(expected)
    for key in expected:
        want = np.asarray(expected[key], dtype=np.int64)
        bad = np.flatnonzero((got[key] != want).reshape(want.shape[0], -1).any(axis=1))
        assert bad.size == 0, (
            f"{case.name}.{key}: {bad.size} of {want.shape[0]} vectors differ; first at {bad[0]}: "
            f"rtl {got[key][bad[0]]} model {want[bad[0]]}; inputs "
            + ", ".join(f"{k}={np.asarray(v)[bad[0]]}" for k, v in stim.items())
        )
