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
from models.backend import Backend, run_compiled
from models.machines.common.results import (
    UNITS,
    CycleResult,
    frame_result,
    publish_pixel_bus,
)
from models.machines.common.slice_order import SliceFaults
from models.machines.common.slices import SliceDatapath
from models.machines.cube4.frame import Cube4Frame
from models.machines.cube4.memory import Cube4Memory
from models.machines.cube4.timing import cube4_lanes, cube4_latency, cube4_pixel_pushes
from models.units import classify as classify_unit
from models.units import interp as interp_unit
from models.units import skew as skew_unit

__all__ = [
    "Faults",
    "Sweep",
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

    def _bilinear(self, q: int, channel: str, cells_a, cells_b) -> np.ndarray:
        (ca, fa, _), (cb, fb, _) = cells_a, cells_b
        planes = self.m.planes(q)
        rows = (ca + 2 - planes["a0"]) * self.m.plane_width + (cb + 2)
        # np.take: a row gather ~20x faster than fancy indexing of a 2-D array.
        corners = np.take(planes[channel], rows, axis=0)
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
        return run_compiled(self.m.kernel, step, factor, state, self)

    def maybe_visible(self) -> np.ndarray | None:
        """False where every corner of a sample's cell classifies to opacity 0."""
        planes = self.m.planes(self.q)
        flags = planes.get("maybe")
        if flags is None:
            return None
        (ca, _, _), (cb, _, _) = self._cells
        return flags[(ca + 2 - planes["a0"]) * self.m.plane_width + (cb + 2)]

    def value(self) -> np.ndarray:
        return self._bilinear(self.q, "value", *self._cells)

    def channels(self) -> list[np.ndarray]:
        return [self._bilinear(self.q, c, *self._cells) for c in "rgba"]

    def gradient(self, sel: np.ndarray) -> np.ndarray:
        m, q = self.m, self.q
        cells_a, cells_b = (tuple(x[sel] for x in cell) for cell in self._cells)
        pa, pb = self.pa[sel], self.pb[sel]
        g = np.empty((pa.size, 3), dtype=np.int64)
        ahead, behind = min(q + 1, m.n_kp - 1), max(q - 1, 0)
        g[:, 2 - m.kp] = self._bilinear(ahead, "value", cells_a, cells_b) - self._bilinear(
            behind, "value", cells_a, cells_b
        )
        for axis, p, cells in ((m.a_ax, pa, cells_a), (m.b_ax, pb, cells_b)):
            up, down = m.cell(p + 1.0, cells), m.cell(p - 1.0, cells)
            if axis == m.a_ax:
                g[:, 2 - axis] = self._bilinear(q, "value", up, cells_b) - self._bilinear(
                    q, "value", down, cells_b
                )
            else:
                g[:, 2 - axis] = self._bilinear(q, "value", cells_a, up) - self._bilinear(
                    q, "value", cells_a, down
                )
        return g


@dataclass
class Sweep:
    """What one pass of a frame's steps over some of its rays produced (all of them in
    one process; a band of them on a worker, :mod:`models.machines.cube4.bands`): the
    samples each pipeline evaluated per step (``busy``, ``(n_steps, P)``), the
    accumulators the pixel bus delivered for ``rays`` and the per-sample counts."""

    rays: np.ndarray
    acc: np.ndarray
    touched: np.ndarray
    dt_sum: np.ndarray | None
    busy: np.ndarray
    samples: int
    skipped: int
    counters: dict[str, int]


class Cube4Machine(Cube4Frame):
    """P Cube-4 pipelines rendering one frame of ``backend``'s plan and scene.

    :meth:`run` is one process's frame: :meth:`sample_pass` over every ray with whole
    slices read from the memory modules through the slice FIFOs (:class:`ModuleSlices`),
    then :meth:`frame`.  A frame split across workers runs :meth:`sample_pass` once per
    band of rays on slices read in bands (:mod:`models.machines.cube4.bands`) and
    :meth:`frame` once on all the sweeps: the timing is the frame's, never a part's.
    """

    def __init__(
        self, backend: Backend, *, faults: Faults | None = None, trace: VcdTrace | None = None
    ) -> None:
        self.faults = faults or Faults()
        self.trace = trace
        super().__init__(backend)  # refusals, slice geometry, buffer capacities
        self.counters = Counters()
        self.elaborated, self.elided = self._elaborate()
        self.need_slices = "gradient" in self.elaborated
        self.datapath = self._slice_datapath()
        self.elaborate_all = backend.exercise_unused
        self.kernel = None
        if backend.compiled:
            from models.machines.cube4.slice_kernel import SliceKernel  # imports numba

            self.kernel = SliceKernel.for_backend(backend, self.a_ax, self.b_ax, self.kp)
        if backend.mode == "composite":
            self._next_visible = backend.transparent_ranges()
        self._current: dict[int, dict[str, np.ndarray]] = {}

    # ------------------------------------------------------------------ slices

    def corner_planes(
        self, stream: np.ndarray, q: int, datapath: SliceDatapath | None = None, a0: int = 0
    ) -> dict:
        """Corner planes of every payload channel of slice ``q`` (promoted by S) from its
        stream through ``datapath`` (default: the whole slice's).  A band's stream holds
        beams ``a0 ..`` only; its module residue is then that of beam ``a0``, and
        ``planes["a0"]`` says which cell the planes' first row is (row ``r``: cell
        ``a0 + r - 2``)."""
        datapath = self.datapath if datapath is None else datapath
        S = self.dp.interp.sample_frac_bits
        payloads = {}
        if self.be.pre_classified:
            rgba = self.be.classified_voxels(stream)
            payloads.update((c, v.reshape(stream.shape)) for c, v in zip("rgba", rgba, strict=True))
        if not self.be.pre_classified or self.be.need_grad or "gradient" in self.elaborated:
            payloads["value"] = stream
        corners = {k: datapath.corners(v, q + a0) << S for k, v in payloads.items()}
        planes: dict = {"a0": a0}
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

    def planes(self, q: int, channel: str | None = None):
        return self._current[q] if channel is None else self._current[q][channel]

    # ------------------------------------------------------------------ frame

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        return self.frame([self.sample_pass(ModuleSlices(self), progress)])

    def sample_pass(self, slices, progress: Callable[[int, int], None] | None = None) -> Sweep:
        """Every step of the plan (``backend.plan``: the frame's, or a band of its rays):
        each sample's pipeline, the hand-offs between pipelines, the back end's stages on
        samples interpolated from the planes ``slices.at(j)`` delivers, and each ray's
        accumulator as the pixel bus takes it after its last sample."""
        be, plan, P, T = self.be, self.plan, self.P, self.T
        state = be.new_state(plan.n_rays)
        counts = Counters()  # per-sample counts of this pass (hand-offs)
        bus = be.new_state(plan.n_rays)
        finishing = _finishing_rays(plan)
        prev_lane = np.full(plan.n_rays, -1, dtype=np.int64)
        busy_k = np.zeros((plan.n_steps, P), dtype=np.int64)
        self.clock = Clock(self.arch.clock_hz)  # for the waveform only
        slices.prime()  # the first slice is read one slice ahead of its samples
        self.clock.advance(T)
        for j, step in enumerate(plan.steps()):
            q = self.slice_of(j)
            self._current = slices.at(j)
            source = HardwareSource(self, step, q)
            lanes = self._lanes(source)
            busy_k[j] = busy = np.bincount(lanes, minlength=P)
            self._hand_off(step.rays, lanes, prev_lane, state, counts)
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
                bus.acc[rays] = state.acc[rays]
                bus.touched[rays] = state.touched[rays]
                if bus.dt_sum is not None:
                    bus.dt_sum[rays] = state.dt_sum[rays]
            if self.trace is not None:
                self._trace_samples(step, q, lanes)
            extra = max(0, int(busy.max(initial=0)) - T)
            self.clock.advance(T + self.arch.slice_overhead_cycles + extra)
            if progress is not None:
                progress(j + 1, plan.n_steps)
        self._current = {}
        ids = plan.ray_ids
        return Sweep(
            rays=ids,
            acc=bus.acc[ids],
            touched=bus.touched[ids],
            dt_sum=None if bus.dt_sum is None else bus.dt_sum[ids],
            busy=busy_k,
            samples=state.samples,
            skipped=int(state.extra.get("skipped", 0)),
            counters=counts.as_dict(),
        )

    def frame(self, sweeps: list[Sweep]) -> CycleResult:
        """The frame of ``sweeps`` (disjoint sets of rays covering the plan): the samples
        per pipeline and step added up, then the frame's timing by its rules -- every
        slice read once (:meth:`_slice_reads`), each slice as long as its busiest
        pipeline, the pixel bus from the whole plan -- and the image from the
        accumulators the bus delivered."""
        be, plan, P, T = self.be, self.plan, self.P, self.T
        c = self.counters
        state = be.new_state(plan.n_rays)
        busy_k = np.zeros((plan.n_steps, P), dtype=np.int64)
        skipped = 0
        for sweep in sweeps:
            state.acc[sweep.rays] = sweep.acc
            state.touched[sweep.rays] = sweep.touched
            if state.dt_sum is not None:
                state.dt_sum[sweep.rays] = sweep.dt_sum
            busy_k += sweep.busy
            state.samples += sweep.samples
            skipped += sweep.skipped
            for key, value in sweep.counters.items():
                c.add(key, value)
        depth = self.faults.pixel_fifo_depth
        depth = self.capacity["pixel_fifo_entries"] if depth is None else depth
        c.set("pixel_bus.fifo_depth", depth)
        if self.need_slices:
            c.set("slice_fifo.depth", T + self.faults.slice_fifo_adjust)
        stages = {
            u: Stage(u, UNITS[u].LATENCY, UNITS[u].II, P, c) for u in UNITS if u in self.elaborated
        }
        prime_reads, reads_k = self._slice_reads()
        extra_k = np.maximum(busy_k.max(axis=1, initial=0) - T, 0)
        block_k = T + self.arch.slice_overhead_cycles + extra_k
        cycles, fifo, tail = self._pixel_bus(busy_k, block_k, reads_k, depth, stages, prime_reads)
        publish_pixel_bus(c, fifo, tail)
        c.set("pixel_bus.stall_cycles", fifo.stall_cycles)
        c.set("simulation.transparent_samples_skipped", skipped)
        image = be.finish(state.acc, state.touched, state.dt_sum)
        return frame_result(self, image, state, cycles, latency=cube4_latency(self.C))

    def _slice_reads(self) -> tuple[np.ndarray, np.ndarray]:
        """Count every slice read of the frame in the memory modules (reads, idle slots,
        the skew check), the module-to-pipeline links and the ring; returns the reads per
        pipeline of the priming read and of each step's read."""
        P, c = self.P, self.counters
        memory = Cube4Memory(None, P, c, shape=self.be.volume.shape)
        memory_out = Channel("pipeline[{}].memory.o", P, c)
        self.memory_stage = Stage("memory", skew_unit.LATENCY, skew_unit.II, P, c)
        idle = np.zeros(P, dtype=np.int64)

        def read(j: int) -> np.ndarray:
            # Module -> pipeline stream: valid in every scheduled slot; Cube-4 never
            # back-pressures inside a slice (stalls happen between slices, at the pixel bus).
            reads = memory.account(self.kp, self.slice_of(j))
            memory_out.account(reads, idle, self.T - reads)
            c.add("ring.link_transfers", 2 * int(reads.sum()))
            return reads

        # The slice FIFOs read each slice one step ahead of its samples (and the first
        # before the first step); without them each step reads its own slice.
        prime = read(0) if self.need_slices else idle
        ahead = 1 if self.need_slices else 0
        reads_k = np.array(
            [read(j + ahead) if j + ahead < self.n_kp else idle for j in range(self.plan.n_steps)],
            dtype=np.int64,
        ).reshape(-1, P)
        memory.publish()
        memory_out.publish()
        return prime, reads_k

    def _pixel_bus(self, busy_k, block_k, reads_k, depth: int, stages: dict, prime_reads):
        """Rules 4-6: every ray pushed into the pixel FIFO when its last sample is written
        back, the bus popping one per clock, the whole machine frozen in a clock where a
        push finds the FIFO full.  Accounts every unit's busy/stall/idle clocks and
        returns ``(cycles, the FIFO's run, clocks after the sequencer's last)``."""
        P, T = self.P, self.T
        idle = np.zeros(P, dtype=np.int64)
        n = len(block_k)
        starts = T + np.concatenate([[0], np.cumsum(block_k)]).astype(np.int64)
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
        # the steps' periods) or after the last one (index n).
        where = np.searchsorted(starts, fifo.frozen_at, side="right") - 1
        counts = np.bincount(where, minlength=starts.size)
        stall_k, tail_stall = counts[:n], int(counts[n])
        tail = cycles - seq_end
        for stage in [self.memory_stage, *stages.values()]:
            prime = prime_reads if stage is self.memory_stage else idle
            stage.account(prime, T)
            if n:
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


class ModuleSlices:
    """Whole slices as one process's machine reads them: from the memory modules (the
    host's write of the whole volume, :class:`Cube4Memory`) through the two slice delay
    FIFOs, each slice's corner planes computed once and kept while a step needs them."""

    def __init__(self, m: Cube4Machine) -> None:
        self.m = m
        self.memory = Cube4Memory(m.be.raw, m.P, Counters(), m.faults.stuck_module)
        depth = m.T + m.faults.slice_fifo_adjust
        self.fifos = (DelayLine(depth, m.P), DelayLine(depth, m.P)) if m.need_slices else None
        self._cache: dict[int, tuple[np.ndarray, dict]] = {}

    def _read(self, j: int) -> np.ndarray:
        m = self.m
        stream, sched = self.memory.read_slice(m.kp, m.slice_of(j))
        if m.trace is not None:
            m._trace_memory(stream, sched.valid)
        return stream

    def prime(self) -> None:
        if self.fifos is not None:
            self.fifos[0].push(self._read(0))

    def _planes_for(self, stream: np.ndarray, q: int) -> dict:
        cached = self._cache.get(q)
        if cached is not None and np.array_equal(cached[0], stream):
            return cached[1]
        planes = self.m.corner_planes(stream, q)
        self._cache[q] = (stream, planes)
        return planes

    def at(self, j: int) -> dict[int, dict]:
        """The planes step ``j`` reads: its slice's, and with the slice FIFOs the slices
        before and after it as the FIFOs deliver them."""
        m = self.m
        q = m.slice_of(j)
        if self.fifos is None:
            return {q: m.corner_planes(self._read(j), q)}
        fifo1, fifo2 = self.fifos
        nxt = self._read(j + 1) if j + 1 < m.n_kp else np.zeros((m.P, m.T), np.int64)
        cur_stream = fifo1.push(nxt)
        prev_stream = fifo2.push(cur_stream)
        current = {q: self._planes_for(cur_stream, q)}
        if j + 1 < m.n_kp:
            current[m.slice_of(j + 1)] = self._planes_for(nxt, m.slice_of(j + 1))
        if j >= 1:
            current[m.slice_of(j - 1)] = self._planes_for(prev_stream, m.slice_of(j - 1))
        for old in [k for k in self._cache if abs(k - q) > 1]:
            del self._cache[old]
        return current


def _finishing_rays(plan: SamplePlan) -> Callable[[int], np.ndarray]:
    """``f(j)``: the rays whose last sample is at step ``j`` (they leave on the pixel bus)."""
    order = np.argsort(plan.j_hi, kind="stable")
    bounds = np.searchsorted(plan.j_hi[order], np.arange(plan.n_steps + 1), side="left")
    ids = plan.ray_ids[order]

    def finishing(j: int) -> np.ndarray:
        return ids[bounds[j] : bounds[j + 1]]

    return finishing
