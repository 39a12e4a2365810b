"""Run one frame of the vg500 top in Amaranth's simulator, its four SDRAM devices
(:class:`rtl.vg500.device.SdramDevice`) beside it (tests; slow but no toolchain).

# Ref: rtl/amaranth_run.py (the Cube-4 top's run, the same host steps).
"""

from __future__ import annotations

from collections.abc import Callable

from amaranth import Elaboratable, Module
from amaranth.sim import Simulator

from rtl.frame import decode
from rtl.vg500.device import SdramDevice
from rtl.vg500.frame import Vg500Program
from rtl.vg500.top import PINS_IN, PINS_OUT, Vg500Top

__all__ = ["run_vg500_amaranth", "build_top"]


def build_top(program: Vg500Program) -> Vg500Top:
    inner = program.inner
    return Vg500Top(inner.dp, inner.geo, program.timing, program.slab_entries)


class _Board(Elaboratable):
    """The top and its four devices."""

    def __init__(self, top: Vg500Top, program: Vg500Program):
        self.top, self.program = top, program

    def elaborate(self, platform):
        m = Module()
        m.submodules.top = self.top
        t = self.program.timing
        for k, words in enumerate(self.program.device_words):
            pins = {p: getattr(self.top, f"sdram{k}_{p}") for p in (*PINS_OUT, *PINS_IN)}
            m.submodules[f"sdram{k}"] = SdramDevice(
                pins,
                words,
                banks=len(words) // (self.program.rows * t.columns),  # as the host wrote
                rows=self.program.rows,
                columns=t.columns,
                cl=t.cas_latency,
                bl=t.burst_length,
            )
        return m


def run_vg500_amaranth(
    program: Vg500Program,
    *,
    on_clock: Callable | None = None,
    max_clocks: int = 2_000_000,
):
    """Render ``program``; ``on_clock(ctx, top, clock)`` after every clock of the frame
    (a pin checker).  Returns ``(CycleResult, extras)`` with the held clocks and bursts."""
    top = build_top(program)
    sim = Simulator(_Board(top, program))
    sim.add_clock(1e-8)
    out: dict = {"pixels": []}
    inner = program.inner

    async def bench(ctx):
        for name, value in inner.registers.items():
            ctx.set(getattr(top, name), value)
        ctx.set(top.pixel.ready, 1)
        clock = 0
        for word in inner.load_words():
            ctx.set(top.load.valid, 1)
            ctx.set(top.load.payload.as_value(), word)
            await ctx.tick()
            clock += 1
            if on_clock is not None:
                on_clock(ctx, top, clock)
        ctx.set(top.load.valid, 0)
        while not ctx.get(top.memory_ready):
            await ctx.tick()
            clock += 1
            if on_clock is not None:
                on_clock(ctx, top, clock)
        ctx.set(top.start, 1)
        await ctx.tick()
        clock += 1
        ctx.set(top.start, 0)
        for _ in range(max_clocks):
            _, _, valid, payload, done = await ctx.tick().sample(
                top.pixel.valid, top.pixel.payload, top.done
            )
            clock += 1
            if on_clock is not None:
                on_clock(ctx, top, clock)
            if valid:
                out["pixels"].append(
                    {
                        "ray": int(payload.ray),
                        "acc": [int(payload.acc[k]) for k in range(4)],
                        "mip": int(payload.mip),
                    }
                )
            if done:
                break
        else:
            raise RuntimeError("the vg500 top did not finish")
        for name in ("cycles", "samples", "stall_cycles", "hold_cycles", "bursts"):
            out[name] = ctx.get(getattr(top, name))

    sim.add_testbench(bench)
    sim.run()
    result = decode(inner, out["pixels"], out["cycles"], out["samples"], out["stall_cycles"])
    result.counters["memory.hold_cycles"] = out["hold_cycles"]
    result.counters["memory.bursts"] = out["bursts"]
    return result, out
