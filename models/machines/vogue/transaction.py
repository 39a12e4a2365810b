"""VOGUE's transaction rung: the frame's work spread evenly, the ring at its mean load.

# Ref: models.machines.vogue.config (the model [I]).

Independent of the cycle rung's ray-by-ray dispatch and per-link count: the modules take
``ceil(W / B)`` clocks for the frame's work ``W`` (samples plus each ray's set-up) on
``B`` boards, and each link carries ``(B - 1) / B`` of the volume's bytes.  Shared with
the cycle rung: the plan's ray ranges, the ``[buffers]`` model and the units' latency.
"""

from __future__ import annotations

import math

from models.frame import Frame
from models.functional import pipeline_latency
from models.machines.common.transaction import TxnTiming, report_progress
from models.machines.vogue.config import check_frame, parse_buffers, voxel_bytes

__all__ = ["VogueTransaction"]


class VogueTransaction:
    """The frame as work and ring traffic (``run()``: its timing)."""

    def __init__(self, frame: Frame, *, pixel_fifo_depth: int | None = None) -> None:
        check_frame(frame)
        self.frame, self.B = frame, frame.arch.pipelines
        self.buffers = parse_buffers(frame.arch)

    def run(self) -> TxnTiming:
        frame, B, arch = self.frame, self.B, self.frame.arch
        plan = frame.plan
        rays = int(plan.ray_ids.size)
        samples = int((plan.j_hi - plan.j_lo + 1).sum())
        work = samples + rays * self.buffers.ray_setup_cycles
        modules = -(-work // B)
        volume = math.prod(frame.volume.shape) * voxel_bytes(frame)
        link = volume * (B - 1) // B
        ring = math.ceil(link / self.buffers.ring_bytes_per_second * arch.clock_hz)
        latency = pipeline_latency(frame.scene, frame.transfer.modulates)
        cycles = max(modules, ring) + latency
        report_progress(self, 1, 1)
        counters = {
            "host.rays": rays,
            "modules.samples": samples,
            "modules.busiest_cycles": modules,
            "ring.link_bytes": link,
            "ring.cycles": ring,
            "ring.bottleneck": int(ring > modules),
            "pipeline.latency_cycles": latency,
            "frame.cycles": cycles,
        }
        return TxnTiming(cycles, counters)
