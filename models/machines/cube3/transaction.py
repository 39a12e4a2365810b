"""Cube-3's transaction rung: slabs of equal load through the max-plus closed form.

# Ref: models.machines.cube3.frame (the structure [I]).

Independent of the cycle rung's per-slab sample count and slab-by-slab recurrence: the
plan's samples are spread evenly over the slabs (``S / n`` each, from the rays' ranges),
and the last slab ends at ``max_k (ready_k + (n - k) T)`` with ``T = ceil(S / (n U))``
(the closed form of a two-stage pipeline).  Shared with the cycle rung: the slices'
arrivals (``slab_arrivals``, ``slice_beams``), ``LOOKAHEAD``, the tree's levels, the
``[buffers]`` model and the units' latency.
"""

from __future__ import annotations

import numpy as np

from models.frame import Frame
from models.functional import pipeline_latency
from models.machines.common.transaction import TxnTiming, report_progress
from models.machines.cube3.frame import (
    LOOKAHEAD,
    check_frame,
    parse_buffers,
    principal,
    slab_arrivals,
    slice_beams,
    tree_levels,
)

__all__ = ["Cube3Transaction"]


class Cube3Transaction:
    """The frame as slices and equal slabs (``run()``: its timing)."""

    def __init__(self, frame: Frame, *, pixel_fifo_depth: int | None = None) -> None:
        check_frame(frame)
        self.frame, self.P = frame, frame.arch.pipelines
        self.units = parse_buffers(frame.arch).units

    def run(self) -> TxnTiming:
        frame, plan = self.frame, self.frame.plan
        kp, _ = principal(frame)
        n = frame.volume.shape[kp]
        samples = int((plan.j_hi - plan.j_lo + 1).sum())
        per_slab = -(-samples // (n * self.units))  # clocks of one slab
        per_slice = slice_beams(frame.volume.shape, kp, self.P)
        arrivals = slab_arrivals(n, per_slice)
        ready = arrivals[np.minimum(np.arange(n) + LOOKAHEAD, n - 1)]
        end = int((ready + (n - np.arange(n)) * per_slab).max())
        levels = tree_levels(self.units)
        latency = levels + pipeline_latency(frame.scene, frame.transfer.modulates)
        cycles = end + latency
        report_progress(self, 1, 1)
        counters = {
            "memory.beams": per_slice * n,
            "memory.beams_per_slice": per_slice,
            "units.samples": samples,
            "units.busy_cycles": per_slab * n,
            "tree.levels": levels,
            "pipeline.latency_cycles": latency,
            "frame.cycles": cycles,
        }
        return TxnTiming(cycles, counters)
