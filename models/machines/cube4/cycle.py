"""The Cube-4 machine at cycle fidelity: skewed memory, ring links, delay FIFOs, pixel bus.

# Ref: architectures.md sections 1.1-1.4 (Pfister & Kaufman, VolVis 1996: slice-parallel
#      ray casting, skewed memory, only local neighbour links plus a pixel bus) and 9.1-9.3
#      (units, buffer sizes, latencies [I]).

A frame reads the volume slice by slice along the principal axis, one voxel per module
per clock (:mod:`models.machines.cube4.memory`).  Each slice's stream passes the slice delay
FIFOs (two, when the scene needs z-neighbours for gradients), the ring links and the
beam FIFO (:mod:`models.machines.common.slices`), which deliver every sample cell's corners.
The plan's rays (the geometry unit: :class:`hwsim.golden.SamplePlan`) say which samples
of a slice belong to which base-plane pixel; :class:`HardwareSource` interpolates them
from the delivered corners with ``models.units.interp``, and the shared back end
(:class:`models.backend.Backend`) classifies, shades and composites them into the
compositing buffers.  A ray's accumulator is handed to the next pipeline whenever its
sample's voxel moves to another module; a finished ray leaves over the pixel bus, a FIFO
drained one pixel per clock, and the host assembles the base-plane image only from what
the bus delivered, then warps it (parallel) as the functional rung does.

Timing (every cycle counted, nothing fitted): one slice takes ``n_a ceil(n_b / P)``
clocks plus the arch's ``slice_cycles``; one more slice primes the slice FIFOs; lanes
that owe more samples than a slice has clocks (perspective) stretch the slice; a full
pixel FIFO stalls the compositors; the pipeline latency (sum of the unit ``LATENCY``
constants, the beam alignment ``C + 1`` and the gradient's one-beam look-ahead ``C``:
:func:`models.machines.cube4.timing.cube4_latency`) and the final pixel-bus drain are added.
The hardware is the same whatever the scene: elision only skips *simulating* units whose
results a scene does not use, so it never changes a cycle count.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hwsim.engine import Channel, Clock, Counters, DelayLine, Stage, VcdTrace, freezing_fifo
from hwsim.golden.positions import SamplePlan, Step
from models.backend import Backend
from models.machines.common.results import (
    UNITS,
    CycleResult,
    frame_result,
    publish_pixel_bus,
)
from models.machines.common.slice_order import SliceFaults
from models.machines.cube4.frame import Cube4Frame
from models.machines.cube4.memory import Cube4Memory
from models.machines.cube4.timing import cube4_lanes, cube4_latency, cube4_pixel_pushes
from models.units import classify as classify_unit
from models.units import interp as interp_unit
from models.units import skew as skew_unit

__all__ = [
    "Faults",
    "CycleResult",
    "Cube4Machine",
    "UNITS",
]  # the last two: models.machines.common.results


@dataclass(frozen=True, kw_only=True)
class Faults(SliceFaults):
    """Cube-4's faults: those of every slice-order machine (:class:`SliceFaults`) and
    ``slice_fifo_adjust``: entries added to (negative: removed from) the slice delay FIFOs."""

    slice_fifo_adjust: int = 0


class HardwareSource:
    """Samples of one step interpolated from the corners the slice datapath delivered.

    Cells and weights follow the functional rung's float arithmetic exactly: a
    neighbour's position is ``p + 1.0`` or ``p - 1.0`` rounded as float64, and its
    weight is quantised from its own fraction (reused when that fraction is the same
    float, which makes the quantised weight the same by construction).
    """

    def __init__(self, machine: Cube4Machine, step: Step, q: int) -> None:
        self.m, self.q = machine, q
        self.pa = step.zyx[:, machine.a_ax]
        self.pb = step.zyx[:, machine.b_ax]
        self._cells = machine.cell(self.pa), machine.cell(self.pb)

    def _bilinear(self, planes: np.ndarray, cells_a, cells_b) -> np.ndarray:
        (ca, fa, _), (cb, fb, _) = cells_a, cells_b
        # np.take: a row gather ~20x faster than fancy indexing of a 2-D array.
        corners = np.take(planes, (ca + 2) * self.m.plane_width + (cb + 2), axis=0)
        return interp_unit.bilinear(
            corners[:, 0], corners[:, 1], corners[:, 2], corners[:, 3], fa, fb, self.m.dp.interp
        )

    def subset(self, sel: np.ndarray) -> HardwareSource:
        """The same source restricted to samples ``sel``."""
        out = object.__new__(HardwareSource)
        out.m, out.q = self.m, self.q
        out.pa, out.pb = self.pa[sel], self.pb[sel]
        out._cells = tuple(tuple(x[sel] for x in cell) for cell in self._cells)
        return out

    def composite_fused(self, step: Step, factor: np.ndarray | None, state) -> bool:
        """Run the back end's composite stage on ``step`` in one compiled pass
        (:mod:`models.machines.cube4.slice_kernel`) when the frame allows it; False: use
        the unit chain."""
        kernel = self.m.kernel
        table = None if kernel is None else kernel.table(step.dt)
        if table is None:
            return False
        kernel.run(self, step, factor, state, table)
        return True

    def maybe_visible(self) -> np.ndarray | None:
        """False where every corner of a sample's cell classifies to opacity 0."""
        flags = self.m.planes(self.q).get("maybe")
        if flags is None:
            return None
        (ca, _, _), (cb, _, _) = self._cells
        return flags[(ca + 2) * self.m.plane_width + (cb + 2)]

    def value(self) -> np.ndarray:
        return self._bilinear(self.m.planes(self.q, "value"), *self._cells)

    def channels(self) -> list[np.ndarray]:
        return [self._bilinear(self.m.planes(self.q, c), *self._cells) for c in "rgba"]

    def gradient(self, sel: np.ndarray) -> np.ndarray:
        m = self.m
        cells_a, cells_b = (tuple(x[sel] for x in cell) for cell in self._cells)
        pa, pb = self.pa[sel], self.pb[sel]
        cur = m.planes(self.q, "value")
        g = np.empty((pa.size, 3), dtype=np.int64)
        ahead = m.planes(min(self.q + 1, m.n_kp - 1), "value")
        behind = m.planes(max(self.q - 1, 0), "value")
        g[:, 2 - m.kp] = self._bilinear(ahead, cells_a, cells_b) - self._bilinear(
            behind, cells_a, cells_b
        )
        for axis, p, cells in ((m.a_ax, pa, cells_a), (m.b_ax, pb, cells_b)):
            up, down = m.cell(p + 1.0, cells), m.cell(p - 1.0, cells)
            if axis == m.a_ax:
                g[:, 2 - axis] = self._bilinear(cur, up, cells_b) - self._bilinear(
                    cur, down, cells_b
                )
            else:
                g[:, 2 - axis] = self._bilinear(cur, cells_a, up) - self._bilinear(
                    cur, cells_a, down
                )
        return g


class Cube4Machine(Cube4Frame):
    """P Cube-4 pipelines rendering one frame of ``backend``'s plan and scene."""

    def __init__(
        self, backend: Backend, *, faults: Faults | None = None, trace: VcdTrace | None = None
    ) -> None:
        self.faults = faults or Faults()
        self.trace = trace
        super().__init__(backend)  # refusals, slice geometry, buffer capacities
        P = self.P
        self.counters = Counters()
        self.elaborated, self.elided = self._elaborate()
        self.need_slices = "gradient" in self.elaborated
        self.memory = Cube4Memory(backend.raw, P, self.counters, self.faults.stuck_module)
        self.datapath = self._slice_datapath()
        self.elaborate_all = backend.exercise_unused
        self.kernel = None
        if backend.compiled:
            from models.machines.cube4.slice_kernel import SliceKernel  # imports numba

            self.kernel = SliceKernel.for_backend(backend, self.a_ax, self.b_ax, self.kp)
        if backend.mode == "composite":
            self._next_visible = backend.transparent_ranges()
        self._cache: dict[int, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
        self._current: dict[int, dict[str, np.ndarray]] = {}

    # ------------------------------------------------------------------ slices

    def _corners(self, stream: np.ndarray, q: int) -> dict[str, np.ndarray]:
        """Corner planes of every payload channel of slice ``q`` (promoted by S)."""
        S = self.dp.interp.sample_frac_bits
        payloads = {}
        if self.be.pre_classified:
            rgba = self.be.classified_voxels(stream)
            payloads.update((c, v.reshape(stream.shape)) for c, v in zip("rgba", rgba, strict=True))
        if not self.be.pre_classified or self.be.need_grad or "gradient" in self.elaborated:
            payloads["value"] = stream
        corners = {k: self.datapath.corners(v, q) << S for k, v in payloads.items()}
        planes = {}
        if self.be.mode == "composite" and not self.elaborate_all:
            if self.be.pre_classified:
                planes["maybe"] = corners["a"].max(axis=0).ravel() > 0
            else:
                # Simulation shortcut, not hardware: a cell whose corners span only
                # transparent LUT entries yields transparent samples (lerps are convex).
                value = corners["value"]
                lo, hi = (
                    classify_unit.lut_index(x.ravel(), self.dp.voxel_bits, S, self.dp.classify)
                    for x in (value.min(axis=0), value.max(axis=0))
                )
                planes["maybe"] = self._next_visible[lo] <= hi
        # Interleaved (cells, 4) planes: one gather fetches a cell's four corners.
        planes.update((k, v.reshape(4, -1).T.copy()) for k, v in corners.items())
        return planes

    def _planes_for(self, stream: np.ndarray, q: int) -> dict[str, np.ndarray]:
        cached = self._cache.get(q)
        if cached is not None and np.array_equal(cached[0], stream):
            return cached[1]
        planes = self._corners(stream, q)
        self._cache[q] = (stream, planes)
        return planes

    def planes(self, q: int, channel: str | None = None):
        return self._current[q] if channel is None else self._current[q][channel]

    def _read(self, j: int) -> np.ndarray:
        q = self.slice_of(j)
        stream, sched = self.memory.read_slice(self.kp, q)
        # Module -> pipeline stream: valid in every scheduled slot; Cube-4 never
        # back-pressures inside a slice (stalls happen between slices, at the pixel bus).
        self.memory_out.observe(sched.valid, True)
        self._reads = sched.valid.sum(axis=1)
        self.counters.add("ring.link_transfers", 2 * int(sched.valid.sum()))
        if self.trace is not None:
            self._trace_memory(stream, sched.valid)
        return stream

    # ------------------------------------------------------------------ frame

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        be, plan, P, T = self.be, self.plan, self.P, self.T
        c = self.counters
        state = be.new_state(plan.n_rays)
        depth = self.faults.pixel_fifo_depth
        capacity = self.capacity["pixel_fifo_entries"]
        depth = capacity if depth is None else depth
        c.set("pixel_bus.fifo_depth", depth)
        self.memory_stage = Stage("memory", skew_unit.LATENCY, skew_unit.II, P, c)
        self.memory_out = Channel("pipeline[{}].memory.o", P, c)
        stages = {
            u: Stage(u, UNITS[u].LATENCY, UNITS[u].II, P, c) for u in UNITS if u in self.elaborated
        }
        slice_depth = T + self.faults.slice_fifo_adjust
        fifo1 = DelayLine(slice_depth, P) if self.need_slices else None
        fifo2 = DelayLine(slice_depth, P) if self.need_slices else None
        if self.need_slices:
            c.set("slice_fifo.depth", slice_depth)
        bus = {
            "acc": be.new_state(plan.n_rays).acc,
            "touched": np.zeros(plan.n_rays, dtype=bool),
            "dt_sum": None if state.dt_sum is None else np.zeros_like(state.dt_sum),
        }
        finishing = _finishing_rays(plan)
        prev_lane = np.full(plan.n_rays, -1, dtype=np.int64)
        self.clock = Clock(self.arch.clock_hz)
        idle = np.zeros(P, dtype=np.int64)
        # Prime: the first slice is read one slice ahead of its samples (fixed hardware).
        self._reads = idle
        if self.need_slices:
            fifo1.push(self._read(0))
        prime_reads = self._reads
        self.clock.advance(T)
        steps = plan.steps()
        # Per step: busiest lanes, the block's stall-free clocks, memory reads.
        blocks: list[tuple[np.ndarray, int, np.ndarray]] = []
        for j, step in enumerate(steps):
            q = self.slice_of(j)
            if self.need_slices:
                self._reads = idle
                nxt = self._read(j + 1) if j + 1 < self.n_kp else np.zeros((P, T), np.int64)
                cur_stream = fifo1.push(nxt)
                prev_stream = fifo2.push(cur_stream)
                self._current = {q: self._planes_for(cur_stream, q)}
                if j + 1 < self.n_kp:
                    self._current[self.slice_of(j + 1)] = self._planes_for(
                        nxt, self.slice_of(j + 1)
                    )
                if j >= 1:
                    self._current[self.slice_of(j - 1)] = self._planes_for(
                        prev_stream, self.slice_of(j - 1)
                    )
                for old in [k for k in self._cache if abs(k - q) > 1]:
                    del self._cache[old]
            else:
                self._current = {q: self._corners(self._read(j), q)}
            source = HardwareSource(self, step, q)
            lanes = self._lanes(source)
            busy = np.bincount(lanes, minlength=P)
            extra = max(0, int(busy.max(initial=0)) - T)
            self._hand_off(step.rays, lanes, prev_lane, state)
            if step.rays.size:
                # The back end may drop samples (terminated rays, crop); then the source
                # is rebuilt for the samples that remain.
                be.process(
                    step,
                    lambda s, q=q, src=source, full=step: (
                        src if s is full else HardwareSource(self, s, q)
                    ),
                    state,
                )
            rays = finishing(j)
            if rays.size:
                bus["acc"][rays] = state.acc[rays]
                bus["touched"][rays] = state.touched[rays]
                if bus["dt_sum"] is not None:
                    bus["dt_sum"][rays] = state.dt_sum[rays]
            block = T + self.arch.slice_overhead_cycles + extra
            blocks.append((busy, block, self._reads))
            if self.trace is not None:
                self._trace_samples(step, q, lanes)
            self.clock.advance(block)
            if progress is not None:
                progress(j + 1, plan.n_steps)
        cycles, fifo, tail = self._pixel_bus(blocks, depth, stages, prime_reads)
        self.clock.advance(cycles - self.clock.cycle)
        self.memory.publish()
        self.memory_out.publish()
        publish_pixel_bus(c, fifo, tail)
        c.set("pixel_bus.stall_cycles", fifo.stall_cycles)
        c.set("simulation.transparent_samples_skipped", state.extra.get("skipped", 0))
        image = be.finish(bus["acc"], bus["touched"], bus["dt_sum"])
        return frame_result(self, image, state, cycles, latency=cube4_latency(self.C))

    def _pixel_bus(self, blocks, depth: int, stages: dict, prime_reads):
        """Rules 4-6: every ray pushed into the pixel FIFO when its last sample is written
        back, the bus popping one per clock, the whole machine frozen in a clock where a
        push finds the FIFO full.  Accounts every unit's busy/stall/idle clocks and
        returns ``(cycles, the FIFO's run, clocks after the sequencer's last)``."""
        P, T = self.P, self.T
        idle = np.zeros(P, dtype=np.int64)
        busy_k = np.array([b for b, _, _ in blocks], dtype=np.int64).reshape(-1, P)
        block_k = np.array([n for _, n, _ in blocks], dtype=np.int64)
        reads_k = np.array([r for _, _, r in blocks], dtype=np.int64).reshape(-1, P)
        starts = T + np.concatenate([[0], np.cumsum(block_k)])  # stall-free period starts
        pushes, _, rays = cube4_pixel_pushes(self.plan, starts[:-1], self.n_a, self.n_b, P)
        fifo = freezing_fifo("pixel_bus.fifo", pushes, depth)
        frozen = fifo.frozen_at
        periods = np.concatenate([[0], starts[:-1]])
        #: The bus's events at actual clocks (frozen clocks included), for rtl diffs: each
        #: period's first slot, each frozen clock, each pixel's pop and ray.
        self.bus_events = {
            "period_starts": periods + np.searchsorted(frozen, periods, side="right"),
            "frozen": frozen + np.arange(frozen.size),
            "pops": fifo.pops,
            "rays": rays,
        }
        seq_nominal = int(starts[-1])
        seq_end = seq_nominal + fifo.shift_at(seq_nominal)
        last_pop = int(fifo.pops[-1]) + 1 if fifo.pops.size else 0
        cycles = max(last_pop, seq_end)
        # Frozen clocks fall in the period running at their stall-free clock (index k of
        # the steps' periods) or after the last one (index len(blocks)).
        where = np.searchsorted(starts, fifo.frozen_at, side="right") - 1
        counts = np.bincount(where, minlength=starts.size)
        stall_k, tail_stall = counts[: len(blocks)], int(counts[len(blocks)])
        tail = cycles - seq_end
        for stage in [self.memory_stage, *stages.values()]:
            prime = prime_reads if stage is self.memory_stage else idle
            stage.account(prime, T)
            if blocks:
                busy = reads_k if stage is self.memory_stage else busy_k
                stage.account(busy, block_k + stall_k, stall_k)
            stage.account(idle, tail + tail_stall, tail_stall)
            stage.publish()
        if self.trace is not None and fifo.pops.size:
            pops = fifo.pops
            ends = np.setdiff1d(pops + 1, pops, assume_unique=True)
            cyc = np.concatenate([pops, ends])
            val = np.r_[np.ones(pops.size, np.int64), np.zeros(ends.size, np.int64)]
            self.trace.record("pixel_bus", "o__valid", 1, cyc, val)
        return cycles, fifo, tail

    def _lanes(self, source: HardwareSource) -> np.ndarray:
        """Pipeline evaluating each sample (:func:`~models.machines.cube4.timing.cube4_lanes`)."""
        return cube4_lanes(source.q, source.pa, source.pb, self.n_a, self.n_b, self.P)

    # ------------------------------------------------------------------ trace

    def _trace_memory(self, stream: np.ndarray, valid: np.ndarray) -> None:
        cycles = self.clock.cycle + np.arange(stream.shape[1])
        bits = self.dp.voxel_bits
        for m in range(self.P):
            scope = f"pipeline[{m}].memory"
            self.trace.record(scope, "o__valid", 1, cycles, valid[m])
            self.trace.record(scope, "o__payload", bits, cycles, stream[m])

    def _trace_samples(self, step: Step, q: int, lanes: np.ndarray) -> None:
        if step.rays.size:
            a = np.clip(np.floor(step.zyx[:, self.a_ax] + 0.5), 0, self.n_a - 1).astype(np.int64)
            b = np.clip(np.floor(step.zyx[:, self.b_ax] + 0.5), 0, self.n_b - 1).astype(np.int64)
            t = self.clock.cycle + a * self.C + b // self.P + self.C + 1 + skew_unit.LATENCY
            for m in range(self.P):
                # High on every cycle with a sample, low after the last of each run (a
                # back-to-back sample keeps valid high).
                busy = np.unique(t[lanes == m])
                ends = np.setdiff1d(busy + 1, busy, assume_unique=True)
                cyc = np.concatenate([busy, ends])
                val = np.r_[np.ones(busy.size, np.int64), np.zeros(ends.size, np.int64)]
                self.trace.record(f"pipeline[{m}].interp", "i__valid", 1, cyc, val)


def _finishing_rays(plan: SamplePlan) -> Callable[[int], np.ndarray]:
    """``f(j)``: the rays whose last sample is at step ``j`` (they leave on the pixel bus)."""
    order = np.argsort(plan.j_hi, kind="stable")
    bounds = np.searchsorted(plan.j_hi[order], np.arange(plan.n_steps + 1), side="left")
    ids = plan.ray_ids[order]

    def finishing(j: int) -> np.ndarray:
        return ids[bounds[j] : bounds[j + 1]]

    return finishing
