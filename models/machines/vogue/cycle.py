"""VOGUE at cycle fidelity: host-defined rays on autonomous modules, the ring's load.

# Ref: models.machines.vogue.config (the overview's VOGUE paragraph [V]; the model [I]).

Timing (every cycle counted; ``ring_bytes_per_second`` and ``ray_setup_cycles`` are
parameters, the fitted ones named in the arch files' ``[published]``):

1. the host hands the rays out in raster order, each to the module that will be free
   first (ties: the lowest board); a ray costs its module ``ray_setup_cycles`` plus one
   clock per sample (evenly spaced, every sample of the plan: no early termination);
2. the volume's slabs circulate on the ring: link ``k`` carries every slab but board
   ``k + 1``'s (:func:`~models.machines.vogue.config.ring_link_bytes`), at
   ``ring_bytes_per_second``; a module's last sample cannot be taken before the ring has
   delivered the frame's volume, so the frame is the later of the busiest module and the
   busiest link;
3. the pipeline's latency (:func:`models.functional.pipeline_latency`) is added once.

``ring.bottleneck`` (1: the ring binds, 0: the modules do) says which.  The pixels are the
shared back end's (:func:`models.functional.render_functional`): VOGUE's datapath is the
common units; what this rung adds is the timing.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable

import numpy as np

from hwsim.engine import Counters
from models.backend import Backend
from models.functional import pipeline_latency, render_functional
from models.machines.common.results import CycleResult, counted_result, elaborate_units
from models.machines.vogue.config import check_frame, parse_buffers, ring_link_bytes

__all__ = ["VogueMachine", "module_loads"]


def module_loads(work: np.ndarray, boards: int) -> np.ndarray:
    """Busy clocks of each module when the rays' ``work`` (clocks, raster order) go one
    by one to the module free first (ties: the lowest board)."""
    free = [(0, k) for k in range(boards)]
    for w in work.tolist():
        t, k = heapq.heappop(free)
        heapq.heappush(free, (t + w, k))
    loads = np.zeros(boards, np.int64)
    for t, k in free:
        loads[k] = t
    return loads


class VogueMachine:
    """``pipeline.count`` VOGUE boards rendering one frame."""

    def __init__(self, backend: Backend, *, faults=None, trace=None) -> None:
        self.be, self.arch, self.frame = backend, backend.arch, backend.frame
        check_frame(self.frame)
        self.P = self.arch.pipelines
        self.buffers = parse_buffers(self.arch)
        self.counters = Counters()
        self.elaborated, self.elided = elaborate_units(backend, ("host", "ring"))

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        frame, c, arch = self.frame, self.counters, self.arch
        result = render_functional(frame, progress=progress)
        plan = frame.plan
        order = np.argsort(plan.ray_ids, kind="stable")  # raster order
        samples = (plan.j_hi - plan.j_lo + 1)[order]
        loads = module_loads(samples + self.buffers.ray_setup_cycles, self.P)
        links = ring_link_bytes(frame, self.P)
        ring = math.ceil(int(links.max()) / self.buffers.ring_bytes_per_second * arch.clock_hz)
        latency = pipeline_latency(frame.scene, frame.transfer.modulates)
        busiest = int(loads.max()) if loads.size else 0
        cycles = max(busiest, ring) + latency
        c.set("host.rays", int(samples.size))
        c.set("modules.samples", int(samples.sum()))
        c.set("modules.busiest_cycles", busiest)
        c.set("modules.idlest_cycles", int(loads.min()) if loads.size else 0)
        c.set("ring.link_bytes", int(links.max()))
        c.set("ring.bytes", int(links.sum()))
        c.set("ring.cycles", ring)
        c.set("ring.bottleneck", int(ring > busiest))
        c.set("pipeline.latency_cycles", latency)
        return counted_result(self, result.image, result.samples, result.rays, cycles)
