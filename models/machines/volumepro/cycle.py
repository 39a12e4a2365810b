"""VolumePro 500, EM-Cube and VolumePro 1000 at cycle fidelity: Cube-4's pipelines fed by SDRAM.

# Ref: architectures.md sections 2 (EM-Cube: Cube-4 derived, 4 ASICs, block-skewed SDRAM,
#      sectioning), 3 (VolumePro 500: shear-warp order, two-level mini-block skew,
#      z-supersampling, sectioning with partial rays parked off-chip), 4 (VolumePro 1000:
#      shear-image order, gradients at voxels then interpolated, early ray termination,
#      perspective) and 9.1-9.3 (units, buffers, latencies [I]).

:class:`SlabMachine` is a slice-order machine of the Cube-4 lineage
(:class:`~models.machines.common.slice_order.SliceOrderMachine`) whose memory is
:class:`~models.machines.volumepro.memory.SdramVolume` (mini-blocks in SDRAM, read as bursts and
de-skewed into the Cube-4 slice stream), whose interpolators are trilinear across two voxel
slices (z-supersampling, :class:`TrilinearSource`), whose gradient unit works on samples or
on voxels, and whose frame is timed by :func:`models.machines.volumepro.slab_timing.run_timing` (the
SDRAM controllers, the input buffer, the beam-by-beam pipelines).  The ring links, beam
FIFO, compositing hand-offs, pixel bus and back end are Cube-4's.  Timing rules:
docs/cycle.md ("The VolumePro family").

Two passes, one frame: the *data pass* moves every voxel from the SDRAM words through the
de-skew network, ring links and FIFOs into the interpolators and the back end, section by
section and slice by slice, and records what each beam of each slice did (live samples,
lanes, finishing and parked rays); the *timing pass* replays that record against the
memory (which mini-block beams are read, when they are ready, when the buffer frees them).
Timing never changes data, so the order of the passes changes nothing.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.heap import return_freed_memory
from hwsim.core.threads import frame_threads
from hwsim.engine import Counters, DrainFifo, Stage, VcdTrace
from hwsim.golden.occupancy import occupancy_from_ranges
from hwsim.golden.positions import make_plan
from hwsim.memory import parse_memory
from models.backend import Backend
from models.machines.common.results import UNITS, CycleResult, frame_result, publish_pixel_bus
from models.machines.common.slice_order import SliceFaults, SliceOrderMachine, slice_position
from models.machines.volumepro.fifo_timing import (
    DESKEW_WRITE,
    fifo_end,
    stream_latency,
    uses_slice_fifos,
)
from models.machines.volumepro.fifo_timing import reach as fifo_reach
from models.machines.volumepro.lanes import live_lanes
from models.machines.volumepro.memory import SdramVolume, words_per_voxel
from models.machines.volumepro.skips_kernel import slice_cells
from models.machines.volumepro.slab_timing import pipeline_latency, run_timing, slab_buffers
from models.machines.volumepro.slice_loads import SliceLoads, differences_numpy, load_numpy
from models.machines.volumepro.threads import SectionBook, finish_behind, steps_ahead
from models.machines.volumepro.timing import (
    SliceRecord,
    count_timing,
    frame_period,
    mini_blocks_read,
    record_trace,
    timing_inputs,
)
from models.machines.volumepro.timing_ahead import timing_ahead
from models.machines.volumepro.trilinear import TrilinearSource
from models.units.voxel import converted_planes

__all__ = ["SlabFaults", "SlabMachine", "TrilinearSource"]

_NONE = np.zeros(0, dtype=bool)  # no termination history yet (live_lanes)


@dataclass(frozen=True, kw_only=True)
class SlabFaults(SliceFaults):
    """The VolumePro family's faults: those of every slice-order machine
    (:class:`SliceFaults`) and ``stuck_bank = (k, b, value)``: bank ``b`` of SDRAM module
    ``k`` returns ``value``; ``lost_spill = s``: the partial rays parked at the end of
    section ``s`` are lost; ``slab_buffer_adjust``: entries per pipeline added to (removed
    from) the input buffer."""

    stuck_bank: tuple[int, int, int] | None = None
    lost_spill: int | None = None
    slab_buffer_adjust: int = 0


class SlabMachine(SliceOrderMachine):
    """P VolumePro-family pipelines fed by SDRAM, rendering one frame of ``backend``'s plan."""

    def __init__(
        self,
        backend: Backend,
        *,
        faults: SlabFaults | None = None,
        trace: VcdTrace | None = None,
        steady_state: bool = False,
    ) -> None:
        self.be, self.dp, plan = backend, backend.dp, backend.plan
        self.steady_state = steady_state
        self.faults = faults or SlabFaults()
        self.arch = arch = backend.arch
        self.P = P = arch.pipelines
        self.trace = trace
        self.skipping = arch.early_termination or arch.space_leaping
        if arch.space_leaping and backend.mode == "composite":
            plan = make_plan(backend.scene, backend.volume, plan.kind, occupancy=self._occupancy())
        self.plan = plan
        self._slice_geometry(backend.volume.shape)
        self.memory_cfg = parse_memory(arch.memory, source=arch.source)
        self.capacity = self._slab_buffers()
        self.counters = Counters()
        self.elaborated, self.elided = self._elaborate()
        self.elaborate_all = backend.exercise_unused
        self.voxel_gradients = self.dp.gradient.source == "voxel"
        self.need_value = (
            not backend.pre_classified or backend.need_grad or "gradient" in self.elaborated
        )
        # The voxels a plane at a time unless already converted: the SDRAM image is the
        # frame's copy of them (kept per volume, as the conversion would be).
        raw = backend.__dict__.get("raw")
        self.memory = SdramVolume(
            converted_planes(backend.volume, self.dp.voxel_bits) if raw is None else raw,
            self.memory_cfg,
            P,
            self.counters,
            stuck_module=self.faults.stuck_module,
            stuck_bank=self.faults.stuck_bank,
            source=arch.source,
            words_per_voxel=words_per_voxel(backend.volume, self.memory_cfg),
            kept_for=(backend.volume, self.dp.voxel_bits),
        )
        self.datapath = self._slice_datapath()
        self.weight_one = 1 << self.dp.interp.weight_bits
        self.skip_transparent = backend.mode == "composite" and not self.elaborate_all
        self.loads = SliceLoads(self)
        self.kernel = None
        if backend.compiled:
            from models.machines.volumepro.slab_kernel import SlabKernel  # imports numba

            self.kernel = SlabKernel.for_backend(backend, self)
        if backend.mode == "composite":
            self.next_visible = np.ascontiguousarray(backend.transparent_ranges())
        self._planes: dict[int, dict[str, np.ndarray]] = {}
        self._voxels: dict[int, np.ndarray] = {}
        self._diffed: set[int] = set()  # slices whose gradient planes are in _planes
        self._taps: dict[float, tuple[int, int, int]] = {}  # k_taps by slice position
        # Rule 6: the sequencer reads a slab up to two slabs (four voxel slices) before
        # the slice that consumes it, so it knows the termination mask of that many sample
        # slices earlier.
        self.read_lag = int(np.ceil(4 * plan.scene.render.supersampling))

    # ------------------------------------------------------------------ set-up

    def _occupancy(self):
        """Blocks that can hold a visible sample (:meth:`Backend.occupied_blocks`), for
        space leaping: exact, as the skipping rule."""
        return occupancy_from_ranges(self.be.occupied_blocks())

    def _slab_buffers(self) -> dict[str, int]:
        return slab_buffers(self.arch, self.C)

    # ------------------------------------------------------------------ geometry

    def k_taps(self, pk: np.ndarray) -> tuple[int, int, int]:
        """Principal-axis taps of a step's samples (one slice position per step): the
        functional rung's ``i0``, ``i1`` and quantised weight."""
        p = float(pk[0]) if np.ndim(pk) else float(pk)
        if np.ndim(pk) and pk.size and not (pk == p).all():
            raise AssertionError("samples of one step lie on one slice")
        taps = self._taps.get(p)
        if taps is None:  # once per slice position (the windows and every source ask)
            # The first: all of the frame's slice positions at once (its windows ask each).
            first = [] if self._taps else map(self.slice_position, range(self.plan.n_steps))
            ps = list(dict.fromkeys([*first, p]))
            n = self.n_kp
            c = np.minimum(np.maximum(np.array(ps), 0.0), n - 1.0)
            i0 = np.minimum(np.floor(c), max(n - 2, 0)).astype(np.int64)
            w = self.dp.interp.weight.quantize(c - i0)
            for key, a, b in zip(ps, i0.tolist(), w.tolist(), strict=True):
                self._taps[key] = (a, min(a + 1, n - 1), b)
            taps = self._taps[p]
        return taps

    def nearest_slice(self, pk: np.ndarray) -> int:
        p = float(pk[0]) if pk.size else 0.0
        return int(min(max(np.floor(p + 0.5), 0), self.n_kp - 1))

    def slice_position(self, j: int) -> float:
        """Principal-axis position of sample slice ``j``."""
        return slice_position(self.plan, j, self.forward)

    def window(self, j: int) -> tuple[int, int]:
        """Voxel slices the beams of sample slice ``j`` read: ``i0 - 1 .. i0 + 2``."""
        i0 = self.k_taps(np.array([self.slice_position(j)]))[0]
        return max(i0 - 1, 0), min(i0 + 2, self.n_kp - 1)

    def _sections(self) -> list[tuple[int, int]]:
        """Row bands ``[a0, a1)`` in processing order (the rays' drift direction)."""
        S, n = self.arch.section_width, self.n_a
        if S <= 0 or S >= n:
            return [(0, n)]
        if self.plan.camera.perspective:
            raise InputError(
                "sections need rays that drift one way: perspective rays diverge",
                source=self.arch.source,
                key="overheads.section_width",
                allowed="0 (no sectioning) for perspective views",
            )
        bands = [(a0, min(a0 + S, n)) for a0 in range(0, n, S)]
        delta = np.asarray(self.plan._delta)
        drift = float(delta[..., self.a_ax].ravel()[0]) if delta.size else 0.0
        return bands[::-1] if drift < 0 else bands

    # ------------------------------------------------------------------ slices

    def planes(self, q: int) -> dict[str, np.ndarray]:
        """Corner planes of voxel slice ``q`` (read from SDRAM on first use, kept while the
        slice is in the window)."""
        planes = self._planes.get(q)
        if planes is None:
            planes = self._planes[q] = self._load(q)
        if self._gradient_planes and q not in self._diffed:
            # After the load, not inside it: the differences read slice q + 1, whose own
            # differences are computed when it is used (no chain of loads ahead).
            planes.update(self._differences(q))
            self._diffed.add(q)
        return planes

    def _load(self, q: int) -> dict[str, np.ndarray]:
        """Corner planes of voxel slice ``q`` from the SDRAM words (its voxel plane kept
        for the differences): compiled (:class:`SliceLoads`) unless the frame runs the
        unit chain or is pre-classified (:func:`slice_loads.load_numpy`, the reference)."""
        if self.kernel is None or self.be.pre_classified:
            return load_numpy(self, q)
        planes, self._voxels[q] = self.loads.load(q)
        return planes

    @property
    def _gradient_planes(self) -> bool:
        """Whether slices carry interpolated voxel-gradient planes (``source = "voxel"``)."""
        return self.voxel_gradients and (self.be.need_grad or "gradient" in self.elaborated)

    def _voxel_plane(self, q: int) -> np.ndarray:
        if q not in self._voxels:
            self._planes[q] = self._load(q)
        return self._voxels[q]

    def _differences(self, q: int) -> dict[str, np.ndarray]:
        """The gradient unit at voxels (``source = "voxel"``): central differences of the
        delivered slices ``q - 1, q, q + 1`` (``2 (v[1] - v[0])`` at edges), streamed back
        through the ring and beam FIFO as corner planes to be interpolated."""
        if self.kernel is None:
            return differences_numpy(self, q)
        cur, n = self._voxel_plane(q), self.n_kp
        if n < 2:
            return self.loads.differences(q, cur, cur, 0, cur)
        if q == 0:
            return self.loads.differences(q, cur, self._voxel_plane(1), 2, cur)
        if q == n - 1:
            return self.loads.differences(q, self._voxel_plane(n - 2), cur, 2, cur)
        hi = self._voxel_plane(q + 1)
        return self.loads.differences(q, self._voxel_plane(q - 1), hi, 1, cur)

    def _evict(self, lo: int) -> None:
        """Drop slices behind the window (processing order)."""
        for q in [q for q in self._planes if (q < lo - 1 if self.forward else q > lo + 1)]:
            del self._planes[q]
            self._voxels.pop(q, None)
            self._diffed.discard(q)

    def _slots(self, source) -> tuple[np.ndarray, np.ndarray]:
        """The voxel (row, column) each sample is evaluated at, the nearest to its
        position: its slot, whose pipeline is its lane (rule 8': whose beam reads its
        row)."""
        (ca, _, fa), (cb, _, fb) = source._cells
        a = np.clip(ca + (fa >= 0.5), 0, self.n_a - 1)
        b = np.clip(cb + (fb >= 0.5), 0, self.n_b - 1)
        return a, b

    # ------------------------------------------------------------------ frame

    def run(self, progress: Callable[[int, int], None] | None = None) -> CycleResult:
        be, plan, P = self.be, self.plan, self.P
        state = be.new_state(plan.n_rays)
        sections = self._sections()
        bus = {
            "acc": be.new_state(plan.n_rays).acc,
            "touched": np.zeros(plan.n_rays, dtype=bool),
            "dt_sum": None if state.dt_sum is None else np.zeros_like(state.dt_sum),
        }
        last_j = np.full(plan.n_rays, -1, dtype=np.int64)
        last_j[plan.ray_ids] = plan.j_hi
        # Rule 8': each ray's last sample in a section (record, row, column).
        fifo = uses_slice_fifos(self.arch)
        last_seen = np.zeros((3, plan.n_rays), dtype=np.int64)
        pushes: list[np.ndarray] = []
        prev_lane = np.full(plan.n_rays, -1, dtype=np.int64)
        records: list[SliceRecord] = []
        parked_counts: list[int] = []
        sram_acc = np.zeros_like(state.acc)
        sram_dt = None if state.dt_sum is None else np.zeros_like(state.dt_sum)
        parked = np.zeros(0, dtype=np.int64)
        # Terminated rays save work only on a machine with ERT hardware (rule 6).
        ert_hardware = self.arch.early_termination and be.mode in ("composite", "iso")
        n_slabs, n_u, n_mb = -(-self.n_kp // 2), -(-self.n_a // 2), -(-self.n_b // 2)
        # Mini-blocks a processed beam needs, per section (rule 6: the others are not read).
        needed = np.zeros((len(sections), n_slabs, n_u, n_mb), dtype=bool)
        if not self.skipping:
            for si, (a0, a1) in enumerate(sections):
                needed[si, :, max(a0 - 1, 0) // 2 : (min(a1 + 1, self.n_a - 1)) // 2 + 1] = True
        total = plan.n_steps * len(sections)
        threads = frame_threads()  # helper threads: models/machines/volumepro/threads.py
        behind = finish_behind(self, threads)
        # The timing pass on a thread too where samples decide no reads (timing_ahead.py).
        timed = timing_ahead(self, sections, needed, threads, self._timing_buffers())
        try:
            for si, (a0, a1) in enumerate(sections):
                if parked.size:  # reload the partial rays this section continues
                    state.acc[parked] = sram_acc[parked]
                    if sram_dt is not None:
                        state.dt_sum[parked] = sram_dt[parked]
                book = SectionBook(
                    self, last_j, prev_lane, last_seen if fifo else None, len(records)
                )
                # Termination masks of the last slices: the memory reads a slab while the
                # pipelines are up to ``lag`` sample slices behind (rule 6).
                history: deque[np.ndarray] = deque(maxlen=self.read_lag)
                seen, done = book.seen, book.done  # kept with the steps (threads.py)
                self._planes.clear()
                self._voxels.clear()
                self._diffed.clear()
                ahead = steps_ahead(self, (a0, a1), len(sections) > 1, threads, book)
                for j, (step, (lo, hi), slots) in enumerate(ahead):
                    self._evict(lo if self.forward else hi)
                    busy = np.zeros(P, dtype=np.int64)
                    cost = None
                    fin = np.zeros(0, dtype=np.int64)
                    if step.rays.size:
                        source, a, b, lanes, fin, handoffs = slots
                        # live, known (rule 6) and samples per lane in one compiled pass
                        full = ert_hardware and len(history) == history.maxlen
                        live, known = np.empty((2, step.rays.size), dtype=bool)
                        if not live_lanes(
                            step.rays, state.alive, ert_hardware, history[0] if full else _NONE,
                            lanes, self.skipping, live, known, busy,
                        ):  # fmt: skip
                            raise AssertionError("a sample's lane lies outside the pipelines")
                        if self.skipping:
                            cost = self._live_cells(source, live, known, si, (lo, hi), needed)
                        book.hand_off(handoffs, step.rays, lanes, state)
                        be.process(
                            step,
                            lambda s, src=source, full=step: (
                                src if s is full else TrilinearSource(self, s)
                            ),
                            state,
                        )
                    elif self.skipping:
                        cost = np.zeros(self.n_a, dtype=np.int64)
                    reach = fifo_reach(self, j) if fifo else -1
                    records.append(SliceRecord(si, (lo, hi), cost, busy, int(fin.size), reach))
                    if timed is not None:
                        timed.record(records[-1])
                    if ert_hardware:
                        history.append(state.alive.copy())
                    if progress is not None:
                        progress(si * plan.n_steps + j + 1, total)
                behind.join()  # the section's blends, then its finished rays to the pixel bus
                fin = np.flatnonzero(done)
                for key, value in bus.items():
                    if value is not None:
                        value[fin] = getattr(state, key)[fin]
                parked = np.flatnonzero(seen & ~done)
                parked_counts.append(int(parked.size))
                if timed is not None:
                    timed.parked(parked_counts[-1])
                if fifo:
                    pushes.append(last_seen[:, seen])
                if parked.size:  # park the partial rays in the section SRAM
                    lost = self.faults.lost_spill == si
                    fresh = be.new_state(1)
                    sram_acc[parked] = fresh.acc[0] if lost else state.acc[parked]
                    state.acc[parked] = fresh.acc[0]
                    if sram_dt is not None:
                        sram_dt[parked] = 0 if lost else state.dt_sum[parked]
                        state.dt_sum[parked] = 0
                    if records:
                        records[-1].arrivals += int(parked.size)
        except BaseException:
            if timed is not None:
                timed.close()
            raise
        behind.close()
        # The last slices' corner planes, the SDRAM words and the ring's routes are not
        # read again: dropped before the timing pass (at 512^3 a slice's planes are ~8 MB
        # a channel over a window of four or five slices, the words 0.27 GB, the routes
        # 0.15 GB).
        self._planes.clear()
        self._voxels.clear()
        self._diffed.clear()
        self.memory.release()
        self.datapath.clear_caches()
        _return_freed_memory()
        pushed = np.concatenate(pushes, axis=1) if pushes else np.zeros((3, 0), np.int64)
        return self._finish(state, bus, records, sections, parked_counts, needed, pushed, timed)

    def _live_cells(self, source, live, known, si, window, needed) -> np.ndarray:
        """Rule 6 at one sample slice: the clocks each beam costs (clock groups of P cells
        holding a sample of a live ray, ``live``) and the mini-blocks the memory reads for
        it (marked in ``needed``): those of the cells of rays the sequencer still knew
        alive when it read the slab (``known``, a superset of ``live``); cell ``(a, b)``
        reads voxel rows ``a - 1 .. a + 2`` and columns ``b - 1 .. b + 2`` of the window's
        slices (corners and gradient neighbours)."""
        P, C = self.P, self.C
        if self.kernel is not None:  # compiled (skips_kernel.slice_cells): the same marks
            cost = np.empty(self.n_a, dtype=np.int64)
            blocks = np.empty((-(-self.n_a // 2), -(-self.n_b // 2)), dtype=bool)
            cells = np.empty((self.n_a, C * P), dtype=bool)
            pa, pb = np.ascontiguousarray(source.pa), np.ascontiguousarray(source.pb)
            slice_cells(pa, pb, live, known, P, self.n_b, cells, cost, blocks)
            needed[si, window[0] // 2 : window[1] // 2 + 1] |= blocks
            return cost
        ra = np.clip(np.floor(source.pa), 0, self.n_a - 1).astype(np.int64)
        rb = np.clip(np.floor(source.pb), 0, self.n_b - 1).astype(np.int64)
        cells = np.zeros((self.n_a, C * P), dtype=bool)
        cells[ra[live], rb[live]] = True
        cost = cells.reshape(self.n_a, C, P).any(axis=2).sum(axis=1)
        cells[ra[known], rb[known]] = True
        needed[si, window[0] // 2 : window[1] // 2 + 1] |= mini_blocks_read(cells[:, : self.n_b])
        return cost

    def _timing_buffers(self) -> tuple[DrainFifo, int, int]:
        """The pixel FIFO, the input buffer's entries and its capacity in deliveries."""
        depth = self.faults.pixel_fifo_depth
        pixel_fifo = DrainFifo(
            "pixel_bus.fifo", self.capacity["pixel_fifo_entries"] if depth is None else depth
        )
        entries = self.capacity["slab_buffer_entries"] + self.faults.slab_buffer_adjust
        return pixel_fifo, entries, max(entries, 0) // (4 * self.C)

    def _finish(self, state, bus, records, sections, parked_counts, needed, pushed, timed):
        be, c, P = self.be, self.counters, self.P
        if timed is None:
            deliveries, slices, plan = timing_inputs(self, records, sections, parked_counts, needed)
            pixel_fifo, entries, capacity = self._timing_buffers()
        else:  # played on its thread as the slices came (timing_ahead.py)
            deliveries, slices, plan, timing = timed.join()
            pixel_fifo, entries, capacity = timed.buffers
        c.set("pixel_bus.fifo_depth", pixel_fifo.depth)
        c.set("memory.slab_buffer_entries", max(entries, 0))
        c.set("memory.slab_buffer_mbbs", capacity)
        # The two-frame replay first: the frame's own timing then drops the bursts.
        fifo = None if plan is None else (plan, tuple(pushed), pixel_fifo.depth)
        period = 0
        if self.steady_state:
            period = frame_period(self, deliveries, slices, capacity, fifo)
        if timed is None:
            timing = run_timing(
                self.memory_cfg,
                deliveries,
                slices,
                capacity=capacity,
                pixel_fifo=pixel_fifo,
                counters=c,
                keep_schedules=self.trace is not None,
                compiled=be.compiled,
                keep_bursts=self.trace is not None,
                deskew=0 if fifo is None else DESKEW_WRITE,
            )
        self.timing = timing
        stages = {
            u: Stage(u, UNITS[u].LATENCY, UNITS[u].II, P, c) for u in UNITS if u in self.elaborated
        }
        if slices:
            busy_k = np.array([s.busy for s in slices])
            cycles_k = np.array([b[0] for b in timing.blocks])
            stall_k = np.array([b[1] for b in timing.blocks])
            for stage in stages.values():
                stage.account(busy_k, cycles_k, stall_k)
        if self.trace is not None:
            record_trace(self, timing, deliveries)
        if fifo is None:  # rule 8
            latency = pipeline_latency(self.C)
            drain = pixel_fifo.flush()
            cycles = timing.end + latency + drain
        else:  # rule 8'
            (pixels,) = fifo_end(self, plan, fifo[1], slices, timing, pixel_fifo.depth)
            latency = stream_latency(self.C)
            drain, cycles = pixels.drain, pixels.end
            pixel_fifo.pushed = pixel_fifo.popped = pixel_fifo.busy_cycles = pixels.pushed
            pixel_fifo.max_occupancy = pixels.max_occupancy
            timing.pixel_stall += pixels.freeze
        if self.steady_state:
            c.set("frame.period_cycles", period)
        idle = np.zeros(P, dtype=np.int64)
        for stage in stages.values():
            stage.account(idle, cycles - timing.end)
            stage.publish()
        self.memory.publish()
        frame = records, sections, parked_counts
        count_timing(self, timing, deliveries, slices, frame, needed, plan is not None)
        publish_pixel_bus(c, pixel_fifo, drain)
        c.set("pixel_bus.stall_cycles", timing.pixel_stall)
        c.set("simulation.transparent_samples_skipped", state.extra.get("skipped", 0))
        image = be.finish(bus["acc"], bus["touched"], bus["dt_sum"])
        return frame_result(self, image, state, cycles, latency=latency)


#: Free heap bytes above which the data pass's freed pages go back to the system.  A trim
#: makes the next frame page-fault its arrays in again (7 % of a 128^3 VolumePro 1000 frame
#: on one thread, more on two), so it pays only where the free pages are a real share of
#: the peak: a 128^3 frame leaves ~17 MB free, a 256^3 frame 66-123 MB, a 512^3 frame
#: ~300 MB (0.17 GB of its peak).
_TRIM_FREE_BYTES = 160 << 20


def _return_freed_memory() -> None:
    """The data pass's freed heap pages back to the system where they are a real share of
    the peak (:func:`hwsim.core.heap.return_freed_memory`): its slice-sized arrays (a few
    MB each at 512^2) otherwise stay resident through the timing pass (0.17 GB of a 512^3
    VolumePro 1000 frame's peak)."""
    return_freed_memory(_TRIM_FREE_BYTES)
