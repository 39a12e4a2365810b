"""Cube-3 at cycle fidelity: beams through the de-skewing network, slabs through the units.

# Ref: models.machines.cube3.frame (the sources [V] and the structure [I]).

Timing (every cycle counted, nothing fitted; docs/early-machines.md, "Cube-3"):

1. the memory reads the volume slice by slice along the view's principal axis, front to
   back, one beam of up to n voxels a clock (conflict-free by the skewing), and the
   barrel shifter de-skews a beam a clock into the 2D skewed buffers (slice ``j`` is
   there at ``(j + 1) B + 1``, ``B`` beams a slice);
2. each sample belongs to the slab of its front slice; slab ``k`` starts when slice
   ``k + 2`` is in the buffers and slab ``k - 1`` is done, and takes
   ``ceil(samples / units)`` clocks (``[buffers] units`` interpolation and shading
   units, one sample a clock each);
3. the compositing tree's ``ceil(log2 units)`` levels and the units' latency are added
   once.

Whether the memory or the units bind shows in ``units.wait_cycles`` (clocks the units
waited for slices) against ``units.busy_cycles``.  The pixels are the shared back end's
on the voxels the network delivered (a faulty shifter shows in the image).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from hwsim.engine import Counters
from models.backend import Backend
from models.frame import Frame
from models.functional import pipeline_latency, render_functional
from models.machines.common.results import CycleResult, counted_result, elaborate_units
from models.machines.common.skewed import CubicFrameBuffer
from models.machines.cube3.frame import (
    Cube3Faults,
    check_frame,
    parse_buffers,
    principal,
    slab_arrivals,
    slab_schedule,
    slice_beams,
    tree_levels,
)
from models.machines.cube3.network import deliver_volume

__all__ = ["Cube3Machine", "slab_loads"]


def slab_loads(frame: Frame) -> np.ndarray:
    """Samples of each slab, front to back: a sample at principal coordinate ``q`` belongs
    to its front slice (``floor(q)`` when rays run toward increasing index)."""
    plan, n = frame.plan, frame.volume.shape
    kp, forward = principal(frame)
    loads = np.zeros(n[kp], np.int64)
    for j in range(plan.n_steps):
        sel = np.flatnonzero((plan.j_lo <= j) & (j <= plan.j_hi))
        if sel.size:
            q = plan.position(j, sel)[:, kp]
            front = np.floor(q) if forward else n[kp] - 1 - np.ceil(q)
            np.add.at(loads, np.clip(front, 0, n[kp] - 1).astype(np.int64), 1)
    return loads


class Cube3Machine:
    """A Cube-3 of ``pipeline.count`` memory modules and ``[buffers] units`` units."""

    def __init__(self, backend: Backend, *, faults: Cube3Faults | None = None, trace=None):
        self.be, self.arch, self.frame = backend, backend.arch, backend.frame
        check_frame(self.frame)
        self.faults = faults or Cube3Faults()
        self.P = self.arch.pipelines
        self.units = parse_buffers(self.arch).units
        self.counters = Counters()
        self.elaborated, self.elided = elaborate_units(backend, ("memory", "network"))

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        frame, c = self.frame, self.counters
        volume = frame.volume
        kp, _ = principal(frame)
        memory = CubicFrameBuffer.write(volume.data, self.P)
        delivered, beams, rotated = deliver_volume(memory, kp, self.faults.shifter_offset)
        seen = dataclasses.replace(volume, data=delivered)
        result = render_functional(dataclasses.replace(frame, volume=seen), progress=progress)
        loads = slab_loads(frame)
        per_slice = slice_beams(volume.shape, kp, self.P)
        end, waited = slab_schedule(loads, slab_arrivals(loads.size, per_slice), self.units)
        levels = tree_levels(self.units)
        latency = levels + pipeline_latency(frame.scene, frame.transfer.modulates)
        cycles = end + latency
        c.set("memory.beams", beams)
        c.set("memory.beams_per_slice", per_slice)
        c.set("network.rotated_lanes", rotated)
        c.set("units.samples", int(loads.sum()))
        c.set("units.busy_cycles", int(sum(-(-x // self.units) for x in loads.tolist())))
        c.set("units.wait_cycles", waited)
        c.set("tree.levels", levels)
        c.set("pipeline.latency_cycles", latency)
        return counted_result(self, result.image, result.samples, result.rays, cycles)
