"""The texture slicer's event model (``transaction`` rung): one slice at a time.

# Ref: docs/architectures.md ("texture-slicer"); docs/transaction.md (the 2 % contract).

Each slice is three SimPy activities: the polygon set-up, then the rasterizer (its
fragments over ``P`` pipelines at the fill rate) and the memory (the slice's texel lines
and frame-buffer traffic at ``memory_bytes_per_clock``) running concurrently; the slice
ends when both have.  It shares with the cycle rung the per-slice counts (fragments, and
texel lines from :class:`~models.machines.texslicer.texture.TexelLines`) and the cost
table; it does not cut slices into raster tiles, so a slice whose tiles alternate
between fill-bound and memory-bound comes out shorter than on the cycle rung.
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np
import simpy

from models.frame import Frame
from models.machines.common.transaction import TxnTiming, report_progress
from models.machines.texslicer.config import BLEND_BYTES, LATENCY
from models.machines.texslicer.cycle import frame_params, stack_axis
from models.machines.texslicer.texture import TexelLines
from models.units import interp as interp_unit

__all__ = ["TexSlicerTransaction"]


class TexSlicerTransaction:
    """The event model of ``frame`` on a texture slicer (``run()`` gives the timing).
    ``pixel_fifo_depth`` is accepted and has no effect: fragments blend in place."""

    def __init__(self, frame: Frame, *, pixel_fifo_depth: int | None = None) -> None:
        self.frame, self.plan = frame, frame.plan
        self.params = frame_params(frame)
        self.axis = stack_axis(frame)
        self.P = frame.arch.pipelines

    def _loads(self) -> tuple[np.ndarray, np.ndarray]:
        """Fragments and texel lines of every slice."""
        shape, cfg = self.frame.volume.shape, self.frame.datapath.interp
        texels = TexelLines(shape, self.params.buffers.texture_line, self.axis)
        frags = np.zeros(self.plan.n_steps, dtype=np.int64)
        lines = np.zeros(self.plan.n_steps, dtype=np.int64)
        for j, step in enumerate(self.plan.steps()):
            if step.rays.size:
                taps = interp_unit.interp_taps(step.zyx, shape, cfg)
                frags[j], lines[j] = step.rays.size, texels(taps).size
        return frags, lines

    def run(self) -> TxnTiming:
        p, b = self.params, self.params.buffers
        frags, lines = self._loads()
        env = simpy.Environment()
        setup = self.frame.arch.slice_overhead_cycles
        busy = {"raster": 0, "memory": 0}

        def work(kind: str, clocks: int) -> Generator:
            busy[kind] += clocks
            yield env.timeout(clocks)

        def slices() -> Generator:
            for j in np.flatnonzero(frags):
                yield env.timeout(setup)
                raster = -(-int(frags[j]) // self.P) * p.fragment_clocks
                nbytes = int(lines[j]) * p.line_bytes + int(frags[j]) * BLEND_BYTES
                memory = -(-nbytes // b.memory_bytes_per_clock)
                yield env.all_of(
                    [env.process(work("raster", raster)), env.process(work("memory", memory))]
                )
                report_progress(self, int(j) + 1, self.plan.n_steps)

        env.process(slices())
        env.run()
        counters = {
            "raster.slices": self.plan.n_steps,
            "raster.fragments": int(frags.sum()),
            "raster.busy_cycles": busy["raster"],
            "texture.lines": int(lines.sum()),
            "texture.bytes": int(lines.sum()) * p.line_bytes,
            "framebuffer.bytes": int(frags.sum()) * BLEND_BYTES,
            "memory.busy_cycles": busy["memory"],
            "frame.samples": int(frags.sum()),
        }
        return TxnTiming(int(env.now) + LATENCY, counters)
