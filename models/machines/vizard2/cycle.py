"""VIZARD II at cycle fidelity: ray packets, block cache on SDRAM, ERT and space leaping.

# Ref: architectures.md section 5 (Meissner et al., EGGH 1998 and GH 2002: image-order
#      ray casting from the view plane, trilinear interpolation, post-classification,
#      per-sample Phong, table of pre-computed gradients, geometry-based space leaping,
#      early ray termination [V]; ray queueing, Doggett ISCAS 2000 [V]; VoxelCache, Kanus
#      et al. GH 2003 [V]).  Structure and timing rules below are [I]; docs/cycle.md.

Rays are cast from the image plane (the golden ``ray`` plan).  The ray generator cuts the
image into tiles (``[buffers] ray_tile``, row-major); a tile's rays enter the ray queue
(``ray_queue_entries`` at a time) as one *packet*, and the packet is marched in lock
step: round ``j`` issues sample ``j`` of each of its live rays, ``P`` per clock (lane
``i mod P``), then round ``j + 1`` (ray queueing: neighbouring rays at the same depth, so
consecutive lookups share cache blocks and SDRAM pages).  Each sample's 8 voxels and 8
gradient-table entries come from the block cache (:mod:`models.machines.vizard2.memory`); a
miss stalls the issue until its line is filled over the SDRAM channel
(``hwsim.memory.SdramController``, cycle-exact).  The shared back end
(``models.backend``) interpolates, classifies, shades and composites what the cache
delivered; a packet's accumulators leave through the pixel FIFO when it retires, and
the image is built only from what left.

Timing (every cycle counted, nothing fitted):

1. a round of ``n`` live rays issues its ``n`` samples in ``ceil(n / P)`` clocks;
2. a lookup group that misses waits until its last fill's last beat has arrived, plus one
   clock to write the line; the fill's bursts go to the SDRAM when the group reaches the
   cache (blocking, in order);
3. with early ray termination (``features.early_termination``; composite with a scene
   threshold < 1, or iso's first hit) a ray stops issuing from the first round that
   starts ``FEEDBACK`` clocks or more after its terminating sample issued (the
   compositor's verdict travels back to the ray generator); samples issued meanwhile are
   fetched and discarded (``ert.speculative_samples``).  Without the feature, dead rays
   keep issuing (and fetching) samples the compositor ignores;
4. geometry-based space leaping (``features.space_leaping``, composite and iso): each
   ray's first and last samples are moved past 4^3 blocks the host's occupancy geometry
   marks empty (``SamplePlan.leap``), so those samples are never issued;
5. a retiring packet's pixels enter the pixel FIFO (drained one per clock); a full FIFO
   stalls the issue;
6. the pipeline latency ``FEEDBACK`` and the final FIFO drain are added once.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from hwsim.engine import Clock, Counters, DeadlockError, DrainFifo, Stage, VcdTrace
from hwsim.golden.occupancy import occupancy_from_ranges
from hwsim.golden.positions import SamplePlan, Step
from hwsim.memory import SdramController
from models.backend import Backend, subset_step
from models.machines.common.results import UNITS, CycleResult, elaborate_units, frame_result
from models.machines.vizard2.config import (
    BLOCK,
    FEEDBACK,
    FILL_WRITE,
    LOOKUP_LATENCY,
    VizardFaults,
    check_frame,
    memory_of,
    parse_buffers,
)
from models.machines.vizard2.memory import BlockCache, CacheFetch, VolumeImage
from models.machines.vizard2.ray_kernel import RayKernel
from models.units import interp as interp_unit

__all__ = ["VizardMachine", "VizardFaults", "UNITS"]


class CacheSource:
    """Samples of one step interpolated from the voxels the block cache delivered."""

    def __init__(self, machine: VizardMachine, fetch: CacheFetch, frac: np.ndarray, pick):
        self.m, self.fetch, self.frac, self.pick = machine, fetch, frac, pick

    def _interp(self, corners: np.ndarray, frac: np.ndarray) -> np.ndarray:
        n = corners.shape[1]
        taps = interp_unit.InterpTaps(np.arange(8 * n).reshape(8, n), frac)
        return interp_unit.interpolate(corners.ravel(), taps, self.m.dp.interp)

    def value(self) -> np.ndarray:
        return self._interp(self.fetch.corners()[:, self.pick], self.frac[:, self.pick])

    def channels(self) -> list[np.ndarray]:
        raw = self.fetch.corners()[:, self.pick]
        rgba = self.m.be.classified_voxels(raw)  # the LUT on the cache's output [I]
        frac = self.frac[:, self.pick]
        return [self._interp(c.reshape(raw.shape), frac) for c in rgba]

    def gradient(self, sel: np.ndarray) -> np.ndarray:
        which = self.pick[sel]
        frac = self.frac[:, which]
        return np.stack(
            [self._interp(self.fetch.gradient_corners(which, c), frac) for c in range(3)], axis=1
        )


class VizardMachine:
    """P VIZARD II pipelines rendering one frame of ``backend``'s plan and scene."""

    def __init__(
        self, backend: Backend, *, faults: VizardFaults | None = None, trace: VcdTrace | None = None
    ) -> None:
        self.be, self.dp, self.arch, plan = backend, backend.dp, backend.arch, backend.plan
        self.trace = trace
        arch = self.arch
        self.faults = faults or VizardFaults()
        self.P = arch.pipelines
        check_frame(backend.frame)
        self.buffers = parse_buffers(arch)
        self.memory_cfg = memory_of(arch)
        self.counters = Counters()
        self.elaborated, self.elided = self._elaborate()
        self.image = VolumeImage(
            backend.raw,
            self.memory_cfg,
            voxel_bits=self.dp.voxel_bits,
            gradients=backend.need_grad,
            stuck_word=self.faults.stuck_word,
            stuck_bank=self.faults.stuck_bank,
            source=arch.source,
            volume=backend.volume,
        )
        self.cache = BlockCache(
            self.buffers.cache_sets,
            self.image,
            corrupt_line=self.faults.corrupt_line,
            dropped_fill=self.faults.dropped_fill,
        )
        # Rays end early on an opacity threshold (composite) or a first hit (iso).
        ert = backend.ert < 1.0 if backend.mode == "composite" else backend.mode == "iso"
        self.ert = arch.early_termination and ert
        self.full_plan = plan
        self.plan = self._leaped(plan) if arch.space_leaping else plan

    # ------------------------------------------------------------------ set-up

    def _elaborate(self) -> tuple[list[str], list[str]]:
        return elaborate_units(self.be, ("memory", "cache"))

    def _leaped(self, plan: SamplePlan) -> SamplePlan:
        occupied = self.be.occupied_blocks(BLOCK)
        if occupied is None:
            return plan
        leaped = copy.copy(plan)  # leap() rebinds arrays; the caller's plan is untouched
        leaped.leap(occupancy_from_ranges(occupied, BLOCK))
        return leaped

    def _packets(self, queue_depth: int) -> tuple[np.ndarray, np.ndarray]:
        """The ray generator's packets: plan-ray indices in the order it emits them
        (image tiles, ``[buffers] ray_tile``, in row-major order, rays row-major inside a
        tile) and where each packet starts (packet ``k`` is ``order[starts[k] :
        starts[k + 1]]``): each tile cut ``queue_depth`` rays at a time."""
        plan, (th, tw) = self.plan, self.buffers.ray_tile
        width = plan.shape[1]
        rows, cols = plan.ray_ids // width, plan.ray_ids % width
        tile_of = (rows // th) * (-(-width // tw)) + cols // tw
        order = np.lexsort((plan.ray_ids, tile_of))
        if not order.size:
            return order, np.zeros(1, dtype=np.int64)
        edges = np.flatnonzero(np.diff(tile_of[order])) + 1
        tiles = np.concatenate([[0], edges, [order.size]])  # where each tile starts
        per_tile = -(-np.diff(tiles) // queue_depth)  # packets in each tile
        first = np.repeat(np.cumsum(per_tile) - per_tile, per_tile)  # a tile's first packet
        starts = np.repeat(tiles[:-1], per_tile) + queue_depth * (np.arange(first.size) - first)
        return order, np.append(starts, order.size)

    # ------------------------------------------------------------------ frame

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        state, bus, pixel_fifo, packets = self._start()
        kernel = RayKernel.for_machine(self)
        if kernel is not None:  # the compiled ray loop: the same bits, cycles and counters
            totals = kernel.run_frame(packets, state, bus, pixel_fifo, progress)
        else:
            totals = self._run_rounds(packets, state, bus, pixel_fifo, progress)
        return self._finish(state, bus, totals, pixel_fifo)

    def timing(self, progress: Callable[[int, int], None] | None = None) -> dict | None:
        """The frame's cycles and counters without its image: the compiled ray loop with
        the datapath cut to what decides a clock (``RayKernel.timing``: cache, SDRAM,
        issue, and the opacity that ends a ray); None when the frame is out of the
        loop's scope.  The counters are :meth:`run`'s less the pipeline stages' and the
        saturations (the transaction rung's timing-only path)."""
        kernel = RayKernel.for_machine(self)
        if kernel is None:
            return None
        kernel.timing = True
        state, bus, pixel_fifo, packets = self._start()
        kernel.run_frame(packets, state, bus, pixel_fifo, progress)
        drain = pixel_fifo.flush()
        cycles = self.clock.advance(FEEDBACK + drain)
        self._set_counters(pixel_fifo, drain)
        counters = dict(self.counters.items())
        counters["frame.cycles"] = cycles
        return counters

    def _start(self) -> tuple:
        """A frame's ray states (the pipelines' and the pixel bus's), pixel FIFO, clock,
        SDRAM controller and packets (the ray generator's order, ``ray_queue_entries`` at
        a time)."""
        be, plan = self.be, self.plan
        state = be.new_state(plan.n_rays)
        bus = be.new_state(plan.n_rays)
        depth = self.faults.pixel_fifo_depth
        depth = self.buffers.pixel_fifo_entries if depth is None else depth
        pixel_fifo = DrainFifo("pixel_bus.fifo", depth)
        queue_depth = self.faults.ray_queue_entries
        queue_depth = self.buffers.ray_queue_entries if queue_depth is None else queue_depth
        self.sdram = SdramController(self.memory_cfg.sdram)
        self.clock = Clock(self.arch.clock_hz)
        self.issued = 0
        if plan.ray_ids.size and queue_depth <= 0:
            raise DeadlockError(
                f"ray_queue: depth {queue_depth} can never accept a ray; the ray generator "
                f"waits forever with {plan.ray_ids.size} rays pending at cycle 0"
            )
        self._where = np.zeros(plan.ray_ids.size, dtype=np.int64)
        self.terminated_at = np.full(plan.ray_ids.size, np.iinfo(np.int64).max // 2)
        self.speculative = 0
        return state, bus, pixel_fifo, self._packets(queue_depth)

    def _run_rounds(self, packets, state, bus, pixel_fifo, progress) -> tuple:
        """The reference ray loop: each round a chain of unit calls (:meth:`_round`).
        Returns the stage totals (busy per lane, cycles, stalled cycles)."""
        plan, P = self.plan, self.P
        order, starts = packets
        packets = [order[a:b] for a, b in zip(starts[:-1], starts[1:], strict=True)]
        blocks: list[tuple[np.ndarray, int, int]] = [(np.zeros(P, np.int64), 0, 0)]
        retired = 0  # cycle of the last retirement
        for k, packet in enumerate(packets):
            j_lo, j_hi = plan.j_lo[packet], plan.j_hi[packet]
            for j in range(int(j_lo.min()), int(j_hi.max()) + 1):
                live = packet[(j_lo <= j) & (j <= j_hi)]
                if self.ert:  # rule 3: known terminations stop the issue
                    known = self.clock.cycle >= self.terminated_at[live] + FEEDBACK
                    live = live[state.alive[plan.ray_ids[live]] | ~known]
                if live.size:
                    blocks.append(self._round(live, j, state))
            # The packet retires: its accumulators leave through the pixel FIFO.
            rays = plan.ray_ids[packet]
            bus.acc[rays] = state.acc[rays]
            bus.touched[rays] = state.touched[rays]
            if bus.dt_sum is not None:
                bus.dt_sum[rays] = state.dt_sum[rays]
            stall = pixel_fifo.advance(self.clock.cycle - retired, int(rays.size), retired)
            if stall:
                blocks.append((np.zeros(P, np.int64), stall, stall))
                self.clock.advance(stall)
            retired = self.clock.cycle
            if progress is not None:
                progress(k + 1, len(packets))
        busy, cycles, stalls = zip(*blocks, strict=True)
        return np.sum(busy, axis=0), int(sum(cycles)), int(sum(stalls))

    def _round(self, live: np.ndarray, j: int, state):
        """Issue packet step ``j`` (plan rays ``live``): cache lookups, fills, timing and
        the back end.  Returns the block's (busy per lane, cycles, stall cycles)."""
        plan, P, be = self.plan, self.P, self.be
        rays = plan.ray_ids[live]
        zyx = plan.position(j, live)
        taps = interp_unit.interp_taps(zyx, be.volume.shape, self.dp.interp)
        fetch = self.cache.fetch(taps.idx)
        n = live.size
        group = np.arange(n) // P
        now = start = self.clock.cycle
        stall = np.zeros(-(-n // P), dtype=np.int64)
        if fetch.miss_blocks.size:
            self._fill(fetch, start, stall)
        issue = start + group + np.cumsum(stall)[group]
        end = start + -(-n // P) + int(stall.sum())
        if self.trace is not None:
            self._trace_round(now, end, issue, rays)
        self.clock.advance(end - now)
        self.issued += n
        step = Step(
            rays,
            zyx,
            plan._dt if np.isscalar(plan._dt) else plan._dt[live],
            plan._view[live] if plan._view.ndim == 2 else plan._view,
        )
        where = self._where
        where[live] = np.arange(n)
        frac = taps.frac

        def source(s: Step) -> CacheSource:
            # The back end may drop samples (terminated rays, crop): find the rest.
            pick = np.arange(n) if s is step else where[np.searchsorted(plan.ray_ids, s.rays)]
            return CacheSource(self, fetch, frac, pick)

        if self.ert:
            before = state.alive[rays]
            self.speculative += n - int(before.sum())
        be.process(step, source, state)
        if self.ert:  # the issue cycle of each ray's terminating sample
            ended = before & ~state.alive[rays]
            self.terminated_at[live[ended]] = issue[ended]
        busy = np.bincount(np.arange(n) % P, minlength=P)
        return busy, end - now, int(stall.sum())

    def _trace_round(self, now: int, end: int, issue: np.ndarray, rays: np.ndarray) -> None:
        """Per lane: ``i__valid`` high in the clocks it issues a sample, ``i__payload`` the
        sample's ray (pixel index)."""
        cycles = np.arange(now, end)
        lanes = np.arange(issue.size) % self.P
        for m in range(self.P):
            valid = np.zeros(cycles.size, dtype=np.int64)
            payload = np.zeros(cycles.size, dtype=np.int64)
            mine = lanes == m
            valid[issue[mine] - now] = 1
            payload[issue[mine] - now] = rays[mine]
            self.trace.record(f"pipeline[{m}].cache", "i__valid", 1, cycles, valid)
            self.trace.record(f"pipeline[{m}].cache", "i__payload", 32, cycles, payload)

    def _trace_memory(self, schedule, cycles: int) -> None:
        """``memory.o__valid``: high in every clock a data beat arrives."""
        sd = self.memory_cfg.sdram
        beats = np.zeros(cycles + 1, dtype=np.int64)
        first = sd.to_pipeline_cycles(schedule.data_first)
        end = sd.to_pipeline_cycles(schedule.data_end)
        np.add.at(beats, np.minimum(first, cycles), 1)
        np.add.at(beats, np.minimum(end, cycles), -1)
        self.trace.record("memory", "o__valid", 1, np.arange(cycles + 1), np.cumsum(beats) > 0)

    def _fill(self, fetch: CacheFetch, start: int, stall: np.ndarray) -> None:
        """Rule 2: each lookup group that misses sends its fills' bursts to the SDRAM when
        it reaches the cache and waits for the last beat (``stall[g]`` += the wait)."""
        sd = self.memory_cfg.sdram
        miss_group = fetch.miss_samples // self.P
        cuts = np.flatnonzero(np.diff(miss_group)) + 1
        waited = 0
        for g, blocks in zip(
            np.split(miss_group, cuts), np.split(fetch.miss_blocks, cuts), strict=True
        ):
            arrive = start + int(g[0]) + waited
            banks, rows = self.image.bursts(blocks)
            order = np.lexsort((rows, banks))  # the fills of one group sorted page by page
            first = len(self.sdram)
            earliest = int(sd.to_memory_cycles(arrive))
            self.sdram.issue_many(banks[order], rows[order], np.full(order.size, earliest))
            last = max(self.sdram.data_end(i) for i in range(first, len(self.sdram)))
            ready = int(sd.to_pipeline_cycles(last)) + FILL_WRITE
            if ready > arrive:
                stall[int(g[0])] += ready - arrive
                waited += ready - arrive

    def _finish(self, state, bus, totals, pixel_fifo) -> CycleResult:
        """Counters and image; ``totals``: the rounds' stage totals (busy per lane,
        cycles, stalled cycles: a stage's accounting is a sum over its blocks)."""
        c, P = self.counters, self.P
        stages = [Stage("cache", LOOKUP_LATENCY, 1, P, c)] + [
            Stage(u, UNITS[u].LATENCY, UNITS[u].II, P, c) for u in UNITS if u in self.elaborated
        ]
        for stage in stages:
            stage.account(*totals)
        drain = pixel_fifo.flush()
        tail = FEEDBACK + drain
        cycles = self.clock.advance(tail)
        idle = np.zeros(P, dtype=np.int64)
        for stage in stages:
            stage.account(idle, tail)
            stage.publish()
        schedule = self._set_counters(pixel_fifo, drain)
        if self.trace is not None:
            self._trace_memory(schedule, cycles)
        image = self.be.finish(bus.acc, bus.touched, bus.dt_sum)
        # ``samples`` is the frame's planned count on every rung (the functional and
        # transaction rungs report it too); what the machine issued and composited are
        # counters.
        self.counters.set("frame.composited_samples", state.samples)
        return frame_result(
            self, image, state, cycles, latency=FEEDBACK, samples=self._frame_samples(state)
        )

    def _frame_samples(self, state) -> int:
        """The frame's samples as every rung counts them (the functional rung's recount,
        :func:`models.leap.visits`): the samples composited, plus those space leaping
        skipped that a live ray passes (a ray's leading empty steps, its trailing ones if
        it never ended, every step of a ray left without samples), as
        :meth:`Backend.process` counts them through the crop box, cut planes and depth
        test."""
        full, plan = self.full_plan, self.plan
        if plan is full:
            return state.samples
        lo, hi = full.j_hi + 1, full.j_hi.copy()  # a ray left without samples: all leading
        where = np.searchsorted(full.ray_ids, plan.ray_ids)
        lo[where], hi[where] = plan.j_lo, plan.j_hi
        alive = state.alive[full.ray_ids]
        be = self.be
        if be.scene.crop is None and not be.scene.cut_planes and be.depth is None:
            lead = int(np.sum(lo - full.j_lo))
            return state.samples + lead + int(np.sum((full.j_hi - hi)[alive]))
        skipped = 0
        for j, step in enumerate(full.steps()):
            at = np.searchsorted(full.ray_ids, step.rays)
            step, _ = be.masks(subset_step(step, (j < lo[at]) | ((j > hi[at]) & alive[at])))
            skipped += step.rays.size
        be.stopped = None  # the depth test's record of rays it ends: this recount's only
        return state.samples + skipped

    def _set_counters(self, pixel_fifo: DrainFifo, drain: int):
        """The memory's, cache's, pixel bus's and frame's counters; returns the SDRAM
        schedule."""
        c = self.counters
        schedule = self.sdram.schedule(copy=False)  # the frame's own controller: views
        for key, value in schedule.stats.to_counters("memory").items():
            c.set(key, value)
        c.set("cache.lines", self.cache.lines)
        c.set("cache.lookups", self.cache.lookups)
        c.set("cache.hits", self.cache.hits)
        c.set("cache.misses", self.cache.lookups - self.cache.hits)
        c.set("cache.fills", self.cache.fills)
        c.set("ray_generator.rays", self.plan.ray_ids.size)
        c.set("pixel_bus.pixels", pixel_fifo.pushed)
        c.set("pixel_bus.busy_cycles", pixel_fifo.busy_cycles)
        c.set("pixel_bus.max_occupancy", pixel_fifo.max_occupancy)
        c.set("pixel_bus.drain_cycles", drain)
        c.set("frame.issued_samples", self.issued)
        c.set("ert.speculative_samples", self.speculative)
        c.set("frame.planned_samples", self.full_plan.samples)
        c.set("frame.leaped_samples", self.full_plan.samples - self.plan.samples)
        return schedule
