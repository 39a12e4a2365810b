"""Run one frame of the RTL top in Amaranth's own simulator (tests; slow but no toolchain).

# Ref: rtl/top.py (ports), rtl/frame.py (what the host writes).

The voxel memory outside the chip is an Amaranth ``Memory`` initialised with the host's
volume words (:class:`VoxelMemory`), read through the top's ``vmem_*`` ports exactly as
the Verilog testbench's memory is (``rtl/top_bench.py``).
"""

from __future__ import annotations

from amaranth import Elaboratable, Module, unsigned
from amaranth.lib.memory import Memory
from amaranth.sim import Simulator

from rtl.frame import FrameProgram, decode
from rtl.top import Cube4Top

__all__ = ["run_amaranth", "VoxelMemory"]


class VoxelMemory(Elaboratable):
    """``top`` with its voxel memory: one synchronous read per module per clock."""

    def __init__(self, top: Cube4Top, words: list[int]) -> None:
        self.top, self.words = top, words

    def elaborate(self, platform):
        m = Module()
        top, geo = self.top, self.top.geo
        P, B, aw = geo.pipelines, top.dp.voxel_bits, geo.module_addr_bits
        m.submodules.top = top
        m.submodules.voxels = mem = Memory(
            shape=unsigned(P * B), depth=geo.module_words, init=self.words
        )
        for k in range(P):
            port = mem.read_port()
            m.d.comb += [
                port.addr.eq(top.vmem_addr[k * aw : (k + 1) * aw]),
                port.en.eq(top.vmem_en),
                top.vmem_data[k * B : (k + 1) * B].eq(port.data[k * B : (k + 1) * B]),
            ]
        return m


def run_amaranth(program: FrameProgram, *, stall_every: int = 0, vcd: str | None = None):
    """Render ``program`` on :class:`~rtl.top.Cube4Top` in the Amaranth simulator.

    ``stall_every``: refuse the pixel bus every that many clocks (0: never).
    Returns the frame's :class:`~models.machines.cube4.cycle.CycleResult`.
    """
    top = Cube4Top(program.dp, program.geo)
    sim = Simulator(VoxelMemory(top, program.volume_words))
    sim.add_clock(1e-8)
    out: dict = {"pixels": []}

    async def bench(ctx):
        for name, value in program.registers.items():
            ctx.set(getattr(top, name), value)
        ctx.set(top.pixel.ready, 1)
        for word in program.load_words():
            ctx.set(top.load.valid, 1)
            ctx.set(top.load.payload.as_value(), word)
            await ctx.tick()
        ctx.set(top.load.valid, 0)
        ctx.set(top.start, 1)
        await ctx.tick()
        ctx.set(top.start, 0)
        clock = 0
        while True:
            ready = 0 if stall_every and clock % stall_every == 0 else 1
            ctx.set(top.pixel.ready, ready)
            _, _, valid, payload, done = await ctx.tick().sample(
                top.pixel.valid, top.pixel.payload, top.done
            )
            if valid and ready:
                out["pixels"].append(
                    {
                        "ray": int(payload.ray),
                        "acc": [int(payload.acc[k]) for k in range(4)],
                        "mip": int(payload.mip),
                    }
                )
            if done:
                break
            clock += 1
            if clock > 10_000_000:
                raise RuntimeError("the RTL top did not finish")
        out["cycles"] = ctx.get(top.cycles)
        out["samples"] = ctx.get(top.samples)
        out["stalls"] = ctx.get(top.stall_cycles)

    sim.add_testbench(bench)
    if vcd is not None:
        with sim.write_vcd(vcd):
            sim.run()
    else:
        sim.run()
    return decode(program, out["pixels"], out["cycles"], out["samples"], out["stalls"])
