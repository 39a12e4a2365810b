"""The texture slicer's event model (``transaction`` rung): one slice at a time.

# Ref: docs/architectures.md ("texture-slicer"); docs/transaction.md (the 2 % contract).

Each slice is a SimPy process: the polygon set-up, then for each raster tile the
rasterizer (its fragments over ``P`` pipelines at the fill rate) and the memory (its
first-read texel lines and frame-buffer traffic at ``memory_bytes_per_clock``) as two
concurrent activities.  It shares with the cycle rung the per-tile loads
(:func:`~models.machines.texslicer.cycle.tile_loads` over
:class:`~models.machines.texslicer.texture.TexelLines`) and the cost table: a slice-level
model (raster and memory over the slice's totals) came out 5-10 % short on magnified
views, where a slice's first tiles fetch most of its lines and its last ones only
raster, so the tiles are shared and the agreement is a consistency check of the
schedule, not an independent measurement (docs/transaction.md).
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np
import simpy

from models.frame import Frame
from models.machines.common.transaction import TxnTiming, report_progress
from models.machines.texslicer.config import BLEND_BYTES, LATENCY
from models.machines.texslicer.cycle import frame_params, stack_axis, tile_loads
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

    def _loads(self) -> tuple[np.ndarray, np.ndarray, list]:
        """Fragments and texel lines of every slice, and its tiles' raster and memory
        clocks."""
        shape, cfg = self.frame.volume.shape, self.frame.datapath.interp
        texels = TexelLines(shape, self.params.buffers.texture_line, self.axis)
        frags = np.zeros(self.plan.n_steps, dtype=np.int64)
        lines = np.zeros(self.plan.n_steps, dtype=np.int64)
        tiles = [None] * self.plan.n_steps
        for j, step in enumerate(self.plan.steps()):
            if step.rays.size:
                first = texels(interp_unit.interp_taps(step.zyx, shape, cfg))
                frags[j], lines[j] = step.rays.size, first.size
                tiles[j] = tile_loads(int(frags[j]), first, self.params, self.P)
        return frags, lines, tiles

    def run(self) -> TxnTiming:
        p = self.params
        frags, lines, tiles = self._loads()
        env = simpy.Environment()
        setup = self.frame.arch.slice_overhead_cycles
        busy = {"raster": 0, "memory": 0}

        def work(kind: str, clocks: int) -> Generator:
            busy[kind] += clocks
            yield env.timeout(clocks)

        def slices() -> Generator:
            for j in np.flatnonzero(frags):
                yield env.timeout(setup)
                for raster, memory in zip(*tiles[j], strict=True):
                    yield env.all_of(
                        [
                            env.process(work("raster", int(raster))),
                            env.process(work("memory", int(memory))),
                        ]
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
