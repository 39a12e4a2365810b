"""Cube-1's transaction rung: beams as memory accesses, from the skewing's theorem.

# Ref: architectures.md 1.2 ("why a beam is conflict-free" [I, elementary]).

Independent of the cycle rung's per-module count: a beam of ``L`` voxels along a main
axis meets ``L`` consecutive residues of ``x + y + z`` mod n, so it takes
``ceil(L / n)`` accesses, and each beam's selection on the multiple-write bus follows.
Shared with the cycle rung: the rule that a frame reads every column of the buffer,
:func:`~models.machines.cube1.frame.bus_levels` and the units' latency
(:func:`models.functional.pipeline_latency`).
"""

from __future__ import annotations

import numpy as np

from models.frame import Frame
from models.functional import pipeline_latency
from models.machines.common.transaction import TxnTiming, report_progress
from models.machines.cube1.frame import bus_levels, check_frame

__all__ = ["Cube1Transaction"]


class Cube1Transaction:
    """The frame's beams as accesses of the n-module memory (``run()``: its timing)."""

    def __init__(self, frame: Frame, *, pixel_fifo_depth: int | None = None) -> None:
        check_frame(frame)
        self.frame, self.P = frame, frame.arch.pipelines

    def run(self) -> TxnTiming:
        frame = self.frame
        shape, kp = frame.volume.shape, frame.plan.principal_axis
        beams = int(np.prod(shape)) // shape[kp]  # every column along the view axis
        length = shape[kp]
        accesses = np.full(beams, -(-length // self.P), np.int64)
        levels = bus_levels(self.P)
        scene = frame.scene
        latency = pipeline_latency(scene, self.frame.transfer.modulates)
        cycles = int(accesses.sum()) + levels * beams + latency
        report_progress(self, 1, 1)
        counters = {
            "memory.beam_reads": beams,
            "memory.access_cycles": int(accesses.sum()),
            "memory.voxels_read": beams * length,
            "bus.levels": levels,
            "bus.beams": beams,
            "bus.select_cycles": levels * beams,
            "pipeline.latency_cycles": latency,
            "frame.cycles": cycles,
        }
        return TxnTiming(cycles, counters)
