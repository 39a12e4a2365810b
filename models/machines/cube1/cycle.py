"""Cube-1 at cycle fidelity: beams read from the skewed frame buffer, selected on the bus.

# Ref: architectures.md 1.1-1.2 (the skewed cubic frame buffer [V], its module formula
#      [I]); models.machines.cube1.frame (the beams and the bus).

Timing (every cycle counted, nothing fitted; docs/early-machines.md, "Cube-1"):

1. the host has written the volume into the n modules (not timed: a frame projects a
   resident volume);
2. the frame reads every beam of the buffer (a column of voxels along the view axis,
   one plan ray where the ray takes samples), one memory access per cycle; a beam with
   ``c`` voxels in its busiest module takes ``c`` cycles (``c = 1`` for beams of at most
   n voxels: conflict-free);
3. then the multiple-write bus selects along the beam in ``ceil(log2 n)`` bus cycles
   (:func:`~models.machines.cube1.frame.bus_levels`) before the next beam is read;
4. the units the scene uses (:func:`models.functional.pipeline_latency`) add their
   latency once.  The memory or the bus binds: ``memory.access_cycles`` against
   ``bus.select_cycles``.

The pixels are those of the shared back end (:func:`models.functional.render_functional`)
on the voxels the modules returned, de-skewed: the memory is what this rung adds, so a
module fault shows in the image and the rung's bits equal the functional rung's exactly
when the memory delivers the volume.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from hwsim.engine import Counters
from models.backend import Backend
from models.functional import pipeline_latency, render_functional
from models.machines.common.results import CycleResult, counted_result, elaborate_units
from models.machines.common.skewed import CubicFrameBuffer, beam_cycles
from models.machines.cube1.frame import Cube1Faults, beam_voxels, bus_levels, check_frame

__all__ = ["Cube1Machine"]


class Cube1Machine:
    """A Cube-1 of ``pipeline.count`` memory modules projecting one frame."""

    def __init__(self, backend: Backend, *, faults: Cube1Faults | None = None, trace=None):
        self.be, self.arch, self.frame = backend, backend.arch, backend.frame
        check_frame(self.frame)
        self.faults = faults or Cube1Faults()
        self.P = self.arch.pipelines  # n memory modules, n voxels of a beam per access
        self.counters = Counters()
        self.elaborated, self.elided = elaborate_units(backend, ("memory", "bus"))

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        frame, c = self.frame, self.counters
        volume = frame.volume
        memory = CubicFrameBuffer.write(volume.data, self.P, self.faults.stuck_module)
        voxels, beam, n_beams = beam_voxels(frame)
        reads = beam_cycles(memory.module_of(voxels), beam, n_beams, self.P)
        delivered = np.zeros_like(volume.data)
        delivered[tuple(voxels.T)] = memory.read(voxels)  # de-skewed by module and address
        seen = dataclasses.replace(volume, data=delivered)
        result = render_functional(dataclasses.replace(frame, volume=seen), progress=progress)
        levels = bus_levels(self.P)
        beams = int(np.count_nonzero(reads))
        latency = pipeline_latency(frame.scene, frame.transfer.modulates)
        cycles = int(reads.sum()) + levels * beams + latency
        c.set("memory.beam_reads", int(n_beams))
        c.set("memory.access_cycles", int(reads.sum()))
        c.set("memory.conflict_cycles", int(reads.sum() - np.count_nonzero(reads)))
        c.set("memory.voxels_read", int(voxels.shape[0]))
        c.set("bus.levels", levels)
        c.set("bus.beams", beams)
        c.set("bus.select_cycles", levels * beams)
        c.set("pipeline.latency_cycles", latency)
        return counted_result(self, result.image, result.samples, result.rays, cycles)
