"""VIRIM at cycle fidelity: boards of resampler, ray buffers and ray casters.

# Ref: models/machines/virim/config.py (the board schedule, its sources and what is [I]).

Rays are the golden ``ray`` plan's (host-independent: the resampling unit samples each
ray at evenly spaced positions; parallel and perspective [V]).  Every ray's samples are
timed ray by ray on its board (:func:`~models.machines.virim.config.board_schedule`);
the frame ends when the busiest board's last ray is composited, plus the latency.  The
image: the resampling unit's table-driven trilinear interpolation (weights from the
``[formats] interp`` table of ``2**weight_bits`` entries per axis) feeds the shared back
end's classification, shading and compositing, step by step, so it is the functional
rung's bit for bit.  No early ray termination: every sample of a ray is cast.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hwsim.engine import Counters, VcdTrace
from models.backend import Backend
from models.machines.common.results import CycleResult, elaborate_units, frame_result
from models.machines.common.taps import TapSamples, VoxelArrays
from models.machines.virim.config import LATENCY, board_of, board_schedule, buffers_of
from models.units import interp as interp_unit

__all__ = ["VirimMachine"]


class VirimMachine:
    """``P`` VIRIM boards rendering ``backend``'s frame."""

    def __init__(self, backend: Backend, *, faults=None, trace: VcdTrace | None = None) -> None:
        self.be, self.arch, self.plan = backend, backend.arch, backend.plan
        self.dp, self.P = backend.dp, backend.arch.pipelines
        self.buffers = buffers_of(self.arch)
        self.counters = Counters()
        self.elaborated, self.elided = elaborate_units(backend, ("resampler", "raycaster"))

    def _image(self, state, progress) -> None:
        be, plan = self.be, self.plan
        arrays = VoxelArrays(be)
        where = np.zeros(plan.n_rays, dtype=np.int64)
        for j, step in enumerate(plan.steps()):
            if step.rays.size:
                taps = interp_unit.interp_taps(step.zyx, be.volume.shape, self.dp.interp)
                where[step.rays] = np.arange(step.rays.size)

                def source(s, taps=taps):
                    return TapSamples(arrays, taps, where[s.rays])

                be.process(step, source, state)
            if progress is not None:
                progress(j + 1, plan.n_steps)

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        be, plan, c = self.be, self.plan, self.counters
        state = be.new_state(plan.n_rays)
        self._image(state, progress)
        samples = plan.j_hi - plan.j_lo + 1
        board = board_of(plan.ray_ids, plan.shape[1], self.P)
        ends, per_board = [], []
        resample = cast = 0
        for k in range(self.P):
            mine = samples[board == k]
            end, r, cc = board_schedule(mine, self.buffers)
            ends.append(end)
            per_board.append(int(mine.sum()))
            resample, cast = resample + r, cast + cc
        busiest = int(np.argmax(ends)) if ends else 0
        cycles = (max(ends) if ends else 0) + LATENCY
        c.set("board.count", self.P)
        c.set("board.busiest", busiest)
        c.set("board.busiest_samples", per_board[busiest] if per_board else 0)
        c.set("board.mean_samples", int(np.mean(per_board)) if per_board else 0)
        c.set("resampler.busy_cycles", resample)
        c.set("raycaster.busy_cycles", cast)
        c.set("raycaster.units", self.P * self.buffers.raycasters)
        c.set("frame.planned_samples", int(samples.sum()))
        image = be.finish(state.acc, state.touched, state.dt_sum)
        return frame_result(self, image, state, cycles, latency=LATENCY)
