"""The Cube-4 machine as a SimPy discrete-event model (the ``transaction`` rung's timing).

# Ref: architectures.md sections 1.1-1.4 (Pfister & Kaufman, VolVis 1996: slice-parallel
#      pipelines on a skewed memory, one pixel bus) and 9.2-9.3 (buffer sizes, latencies
#      [I]); docs/cycle.md "Timing rules" (the rules this model approximates).

Two cooperating SimPy processes exchange whole slices instead of voxels and clocks:

* **memory**: the P skewed modules read a slice's ``n_a`` beams back to back, ``C =
  ceil(n_b / P)`` clocks per beam, as one batch (the skew never lets two voxels of a beam
  meet in one module, so a beam batch cannot conflict); the finished slice goes into the
  slice FIFO (a :class:`simpy.Store`), which lets the memory run one slice ahead of the
  samples (the primed slice);
* **pipelines**: take a slice, spend ``max(T, busiest lane)`` clocks on it plus the
  machine's per-slice overhead.  On a shear-warp plan the skew spreads a slice's samples
  evenly (``ceil(samples / P)``, never above ``T``); on a shear-image (perspective) plan
  the busiest lane is counted over every planned sample's position with the cycle rung's
  lane rule (:func:`busiest_lanes`).

The pixel bus is then the cycle rung's rule, one copy
(:func:`~models.machines.cube4.timing.cube4_pixel_pushes`,
:func:`hwsim.engine.fifo.freezing_fifo`): each ray pushed when its last sample is written
back, from the position of that one sample; the bus pops one pixel per clock and the
machine freezes in a clock where a push finds the FIFO full.  Sample counts per slice come
from the plan's ray ranges; no voxel is read.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import simpy

from hwsim.engine.fifo import freezing_fifo
from hwsim.golden.positions import SamplePlan
from models.frame import Frame
from models.machines.common.slice_order import slice_direction
from models.machines.common.transaction import TxnTiming, report_progress, slice_loads
from models.machines.cube4.frame import check_cube4_frame, cube4_buffers
from models.machines.cube4.timing import (
    cube4_lanes,
    cube4_latency,
    cube4_pixel_pushes,
)

__all__ = ["Cube4Geometry", "Cube4Transaction", "busiest_lanes"]


@dataclass(frozen=True)
class Cube4Geometry:
    """What sets a Cube-4 frame's length: pipelines, slice shape and buffer depths."""

    pipelines: int
    slices: int
    beams: int  # n_a: beams per slice
    beam_voxels: int  # n_b: voxels per beam
    slice_overhead: int
    pixel_fifo_depth: int

    @property
    def beam_cycles(self) -> int:
        """``C``: clocks one beam takes (each pipeline reads ``ceil(n_b / P)`` voxels)."""
        return -(-self.beam_voxels // self.pipelines)

    @property
    def slice_cycles(self) -> int:
        """``T = n_a C``: clocks the memory spends on one slice."""
        return self.beams * self.beam_cycles

    @property
    def latency(self) -> int:
        """Address/de-skew, beam alignment ``C + 1``, the gradient's look-ahead ``C`` and
        every unit's latency (the cycle rung's rule 5, one copy)."""
        return cube4_latency(self.beam_cycles)


def busiest_lanes(plan: SamplePlan, pipelines: int) -> np.ndarray:
    """Samples of the busiest pipeline at each step of a shear-image (perspective) plan,
    counted exactly with the cycle rung's lane rule
    (:func:`~models.machines.cube4.timing.cube4_lanes`) over every planned sample's position
    (:func:`models.fused_steps.plan_positions`, compiled)."""
    from models import fused_steps  # imports numba: only for the frames that need it

    kp = plan.principal_axis
    a_ax, b_ax = (ax for ax in range(3) if ax != kp)
    shape = plan.volume.shape

    def lanes_of(zyx: np.ndarray) -> np.ndarray:
        q = int(zyx[0, kp])  # every sample of a step lies on its slice
        return cube4_lanes(q, zyx[:, a_ax], zyx[:, b_ax], shape[a_ax], shape[b_ax], pipelines)

    return fused_steps.busiest_lanes(plan, pipelines, lanes_of)


class Cube4Transaction:
    """SimPy model of one Cube-4 frame at slice / beam-batch granularity.

    Parameters
    ----------
    scene : Scene
    arch : ArchConfig
        A slice-parallel machine.
    plan : SamplePlan
        The frame's sample plan (``slice-parallel``).
    pixel_fifo_depth : int, optional
        Override of ``[buffers] pixel_fifo_entries`` (studies of a shallow pixel FIFO).
    """

    def __init__(self, frame: Frame, *, pixel_fifo_depth: int | None = None) -> None:
        arch, plan = frame.arch, frame.plan
        check_cube4_frame(frame)  # the cycle rung's refusals, one copy
        self.plan = plan
        kp = plan.principal_axis
        a_ax, b_ax = (ax for ax in range(3) if ax != kp)
        shape = plan.volume.shape
        C = -(-shape[b_ax] // arch.pipelines)
        depth = cube4_buffers(arch, C, shape[a_ax] * C)["pixel_fifo_entries"]
        self.geo = Cube4Geometry(
            pipelines=arch.pipelines,
            slices=shape[kp],
            beams=shape[a_ax],
            beam_voxels=shape[b_ax],
            slice_overhead=arch.slice_overhead_cycles,
            pixel_fifo_depth=depth if pixel_fifo_depth is None else pixel_fifo_depth,
        )
        slice_direction(plan)  # one slice order per frame, or refused

    def run(self) -> TxnTiming:
        """Simulate the frame; return its cycles and the event model's counters."""
        start = time.perf_counter()
        geo, P, T = self.geo, self.geo.pipelines, self.geo.slice_cycles
        samples, _ = slice_loads(self.plan)
        if self.plan.kind == "shear-image":
            # Rays are not one per voxel column: count each pipeline's samples.
            busiest_of = busiest_lanes(self.plan, P)
        else:
            # One ray per base-plane pixel and slice: the skew spreads a slice's samples
            # evenly, at most C per beam per pipeline, so no slice stretches.
            busiest_of = -(-samples // P)
        env = simpy.Environment()
        slice_fifo = simpy.Store(env, capacity=1)
        stats = {"events": 0, "stretch": 0}
        starts: list[int] = []

        def memory():
            for j in range(geo.slices):
                yield env.timeout(T)  # n_a beams of C clocks, no conflicts by the skew
                yield slice_fifo.put(j)
                stats["events"] += 2

        def pipelines():
            for j in range(len(samples)):
                yield slice_fifo.get()
                starts.append(int(env.now))
                busiest = int(busiest_of[j])
                stretch = max(0, busiest - T)
                stats["stretch"] += stretch
                yield env.timeout(T + geo.slice_overhead + stretch)
                stats["events"] += 2
                report_progress(self, j + 1, len(samples))
            starts.append(int(env.now))

        env.process(memory())
        env.process(pipelines())
        env.run()  # until nothing is scheduled: every slice has been processed
        # The pixel bus (rules 4-6): each ray pushed when its last sample is written back,
        # one pop per clock, everything frozen while a push finds the FIFO full; only the
        # rays' last sample positions are computed, no voxel.
        pushes, _, _ = cube4_pixel_pushes(
            self.plan, np.asarray(starts[:-1]), geo.beams, geo.beam_voxels, P
        )
        fifo = freezing_fifo("pixel_bus.fifo", pushes, geo.pixel_fifo_depth)
        seq_end = starts[-1] + fifo.shift_at(starts[-1])
        cycles = max(int(fifo.pops[-1]) + 1 if fifo.pops.size else 0, seq_end)
        voxels = geo.slices * geo.beams * geo.beam_voxels
        counters: dict[str, Any] = {
            "memory.busy_cycles": geo.slices * T,
            "memory.reads": voxels,
            "memory.read_bytes": 2 * voxels,  # 16-bit words, as the cycle model counts
            "pipelines.busy_cycles": -(-int(samples.sum()) // P) if P else 0,
            "pipelines.stall_cycles": fifo.stall_cycles,
            "pipelines.stretch_cycles": stats["stretch"],
            "pixel_bus.pixels": fifo.pushed,
            "pixel_bus.busy_cycles": fifo.busy_cycles,
            "pixel_bus.max_occupancy": fifo.max_occupancy,
            "pixel_bus.drain_cycles": cycles - seq_end,
            "pipeline.latency_cycles": geo.latency,
            "frame.cycles": cycles,
            "frame.samples": int(samples.sum()),
            "transaction.events": stats["events"] + fifo.pushed,
            "transaction.granularity": "slice (n_a beam batch) / pixel",
            "transaction.timing_seconds": time.perf_counter() - start,
        }
        return TxnTiming(int(cycles), counters)
