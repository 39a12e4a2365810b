"""The texture slicer at cycle fidelity: slices rasterized tile by tile, texture units,
texel-line fetches and frame-buffer blending sharing one memory.

# Ref: shared/docs/reference/000_d6a752d96745b32a.txt ("General-purpose rendering
#      hardware" [V]: 2-D stacks or 3-D textures, slices composited in depth order);
#      docs/architectures.md ("texture-slicer": the rules below; all timing [I]).

Every step of the plan is one textured polygon (a slice of the chosen 2-D stack, or a
view-aligned plane through the 3-D texture); its fragments are the rays the plan samples
there, rasterized in ray order in tiles of ``[buffers] raster_tile`` fragments.  Timing:

1. polygon set-up costs ``[overheads] slice_cycles`` per slice;
2. a tile's fragments leave ``P`` pixel pipelines at one per ``fragment_clocks`` clocks
   each (the fill rate: texture-unit clocks per fragment over ``texture_units``);
3. the tile's memory traffic -- the texel lines it reads first in this slice and the
   frame-buffer read-modify-write of every fragment -- takes
   ``ceil(bytes / memory_bytes_per_clock)`` clocks on the one memory;
4. raster and memory overlap within a tile, so a tile takes the larger of the two;
5. the pipeline latency is added once.

There is no early ray termination: every planned fragment is rasterized and fetched
(the back end ignores the samples of rays already opaque).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hwsim.engine import Counters, VcdTrace
from models.backend import Backend
from models.machines.common.results import CycleResult, elaborate_units, frame_result
from models.machines.common.taps import TapSamples, VoxelArrays
from models.machines.texslicer.config import BLEND_BYTES, LATENCY, params_of
from models.machines.texslicer.texture import TexelLines
from models.units import interp as interp_unit

__all__ = ["TexSlicer", "frame_params", "stack_axis", "tile_loads"]


def tile_loads(n: int, first: np.ndarray, p, P: int) -> tuple[np.ndarray, np.ndarray]:
    """Raster and memory clocks of each tile of a slice of ``n`` fragments whose texel
    lines are first read by fragments ``first`` (rules 2 and 3), on ``P`` pipelines."""
    b = p.buffers
    size = b.raster_tile
    k = -(-n // size)
    frags = np.full(k, size, dtype=np.int64)
    frags[-1] = n - size * (k - 1)
    lines = np.bincount(first // size, minlength=k)
    raster = -(-frags // P) * p.fragment_clocks
    memory = -(-(lines * p.line_bytes + frags * BLEND_BYTES) // b.memory_bytes_per_clock)
    return raster, memory


def frame_params(frame):
    """The texture costs of ``frame`` (lit: RGBA texels; post-classified: a lookup)."""
    scene, be_bits = frame.scene, frame.datapath.voxel_bits
    post = scene.render.mode == "composite" and frame.transfer.order == "post"
    return params_of(frame.arch, lit=scene.lit, post=post, voxel_bytes=-(-be_bits // 8))


def stack_axis(frame) -> int | None:
    """The axis of the 2-D stack the view chose (None: a 3-D texture)."""
    return frame.plan.principal_axis if frame.plan.kind != "ray" else None


class TexSlicer:
    """``P`` pixel pipelines with texture units rendering ``backend``'s frame."""

    def __init__(self, backend: Backend, *, faults=None, trace: VcdTrace | None = None) -> None:
        self.be, self.arch, self.plan = backend, backend.arch, backend.plan
        self.dp, self.P, self.trace = backend.dp, backend.arch.pipelines, trace
        self.params = frame_params(backend.frame)
        self.axis = stack_axis(backend.frame)
        self.counters = Counters()
        self.elaborated, self.elided = elaborate_units(backend, ("rasterizer", "texture"))

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        be, plan, c = self.be, self.plan, self.counters
        state = be.new_state(plan.n_rays)
        memory = VoxelArrays(be)
        texels = TexelLines(be.volume.shape, self.params.buffers.texture_line, self.axis)
        where = np.zeros(plan.n_rays, dtype=np.int64)
        setup = self.arch.slice_overhead_cycles
        cycles = fragments = lines = 0
        raster_busy = memory_busy = fill_bound = memory_bound = 0
        for j, step in enumerate(plan.steps()):
            n = step.rays.size
            if n:
                taps = interp_unit.interp_taps(step.zyx, be.volume.shape, self.dp.interp)
                first = texels(taps)
                raster, mem = tile_loads(n, first, self.params, self.P)
                where[step.rays] = np.arange(n)

                def source(s, taps=taps):
                    return TapSamples(memory, taps, where[s.rays])

                be.process(step, source, state)
                cycles += setup + int(np.maximum(raster, mem).sum())
                fragments += n
                lines += first.size
                raster_busy += int(raster.sum())
                memory_busy += int(mem.sum())
                fill_bound += int((raster >= mem).sum())
                memory_bound += int((raster < mem).sum())
            if progress is not None:
                progress(j + 1, plan.n_steps)
        cycles += LATENCY
        p = self.params
        c.set("raster.slices", plan.n_steps)
        c.set("raster.fragments", fragments)
        c.set("raster.busy_cycles", raster_busy)
        c.set("raster.fragment_clocks", p.fragment_clocks)
        c.set("texture.lines", lines)
        c.set("texture.bytes", lines * p.line_bytes)
        c.set("framebuffer.bytes", fragments * BLEND_BYTES)
        c.set("memory.busy_cycles", memory_busy)
        c.set("bottleneck.fill_tiles", fill_bound)
        c.set("bottleneck.memory_tiles", memory_bound)
        image = be.finish(state.acc, state.touched, state.dt_sum)
        return frame_result(self, image, state, cycles, latency=LATENCY, derive_samples=fragments)
