"""The VolumePro-family machines as a SimPy event model (the ``transaction`` rung's timing).

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rules 1-5, 7 and 8, and 3', 5', 8'
#      (the rules this model approximates); architectures.md section 3 (VolumePro 500: two-level
#      mini-block skew, US 6,266,733 [V abstract]), section 2 (EM-Cube) and 9.1 (voxel
#      memory controller, burst scheduling, refresh).

P pipelines fed by ``[memory] modules`` SDRAM devices through an input (slab) buffer,
as cooperating SimPy processes at *beam-group* granularity:

* **memory**: reads the volume slab by slab (two voxel slices, front to back), each slab
  in ``groups`` chunks of mini-block beams (mbbs: two beams of a slab, ``n_b / 2`` bursts);
  a chunk's bursts go to each module's :class:`hwsim.memory.SdramTransactionPort` (row
  hits, misses, refresh and CAS timed by the shared SDRAM model) and the chunk is *ready*
  when every module has delivered it.  A chunk may not issue before the input buffer has
  room: the chunk ``capacity`` places earlier must have been freed.  The memory process
  only records the cycle each chunk issues; the ports get the bursts when the pipelines
  ask when a chunk is ready, every chunk issued so far in one call per module, each burst
  with its chunk's arrival cycle
  (:class:`~models.machines.volumepro.chunk_reads.DeferredReads`: the controller is
  causal, so the schedule is the per-chunk one), each module's bursts split out and
  checked once per frame;
* **pipelines**: every sample slice (z-supersampling included) is ``groups`` groups of
  beams, ``C = ceil(n_b / P)`` clocks per beam; a group starts when the chunks its rows'
  trilinear windows need (voxel slices ``i0 - 1 .. i0 + 2``, rows ``a - 2 .. a + 2``)
  are ready, and frees the chunks no later group needs; after a slice come the
  per-slice overhead, the stretch of a slice whose busiest pipeline owes more samples
  than its beams have clocks (rays denser than voxels: a magnified shear-image view;
  each sample's pipeline is its nearest voxel's module, :func:`sample_lanes`) and the
  pixel FIFO (:class:`PixelBus`).

Each of the two processes keeps its own clock ahead of SimPy's and yields only where it
waits: the pipelines for a chunk not ready by their clock (or to push pixels, the pixel
bus running on SimPy's clock), the memory for a slot whose freeing the pipelines have not
reached yet (:class:`~models.machines.volumepro.chunk_reads.ChunkLink`).  A run of beam
groups whose chunks are ready costs no event, and the memory issues a chunk at the later
of its predecessor's issue and its slot's freeing: the same cycles as an event per group
and per chunk.

On the slice-FIFO machines (VolumePro 500, EM-Cube: rules 3', 5', 8' of docs/cycle.md,
:func:`~models.machines.volumepro.fifo_timing.uses_slice_fifos`) the groups are those of
:mod:`models.machines.volumepro.fifo_transaction` instead: periods that read each voxel
slice once, a group waiting for the chunks holding its rows of the slice it reads; a
period's finished rays are pushed at its start and leave the stream latency later.

With ``[overheads] section_width`` the slices' beams are processed band by band
(:mod:`models.machines.common.sections`): each band re-reads the mbbs of its rows, pays the
section overhead and reloads the rays the last band parked (one clock each); parked
rays leave over the pixel bus at the end of their band.

What is coarser than the cycle rung (the error's sources): readiness and freeing per
chunk of mbbs instead of per mbb and per beam, so pipelines wait for a whole chunk at the
first fill and wherever the memory is the bottleneck; and the buffer's capacity counted
in whole chunks.  Beam skipping (early ray termination, space leaping: VolumePro 1000)
is the subclass :class:`~models.machines.volumepro.vp1000_transaction.Vp1000Transaction`,
which supplies each slice's per-beam clocks and the mini-blocks read (``skips``); this
class refuses a skipping machine.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from hwsim.core.errors import NotAvailableError
from hwsim.engine.fifo import DeadlockError
from hwsim.golden.positions import SamplePlan
from hwsim.memory import SdramStats, parse_memory
from models.frame import Frame
from models.machines.common.sections import band_loads, bands_of
from models.machines.common.slice_order import slice_direction, slice_position
from models.machines.common.transaction import (
    TxnTiming,
    require_pipeline_clock,
    slice_loads,
)
from models.machines.volumepro.fifo_timing import (
    stream_latency,
    uses_slice_fifos,
)
from models.machines.volumepro.fifo_transaction import chunk_index, fifo_schedule
from models.machines.volumepro.lanes import busiest_lanes, miniblock_layout, sample_lanes
from models.machines.volumepro.memory import words_per_voxel
from models.machines.volumepro.pipeline_events import simulate
from models.machines.volumepro.slab_timing import pipeline_latency, slab_buffers
from models.units import classify, composite, crop, gradient, interp, shade

if TYPE_CHECKING:
    from models.machines.volumepro.vp1000_transaction import BeamSkips

__all__ = ["SlabTransaction", "busiest_lanes", "miniblock_layout", "sample_lanes"]

_PIPELINE_UNITS = (interp, gradient, classify, shade, composite, crop)


class SlabTransaction:
    """SimPy model of one VolumePro 500 / EM-Cube frame (shear-warp or shear-image order).

    Parameters
    ----------
    frame : Frame
        On a machine with a ``[memory]`` table of mini-block SDRAM modules (sections from
        ``[overheads] section_width``).
    groups : int
        Beam groups per slice (and mbb chunks per slab): the model's granularity.
    pixel_fifo_depth : int, optional
        Override of ``[buffers] pixel_fifo_entries``.
    steady_state : bool
        Also play a second identical frame back to back and report the cycles between
        the two frames' ends (``frame.period_cycles``, the cycle rung's rule 9).
    events : str
        How the processes run: ``"compiled"`` (one band, no slice FIFOs and nobody
        listening to progress: :mod:`models.machines.volumepro.pipeline_kernel`; else as
        ``"generators"``), ``"generators"`` (the generator processes on the lean loop
        with SimPy's order, :class:`~models.machines.volumepro.event_loop.EventLoop`) or
        ``"simpy"`` (on ``simpy.Environment``: the reference).  The same results.
    """

    #: Whether the class models beam skipping (its subclass for VolumePro 1000 does).
    models_skipping = False
    #: Rule 6's per-beam clocks and mini-blocks read (set by a skipping subclass).
    skips: BeamSkips | None = None

    def __init__(
        self,
        frame: Frame,
        *,
        groups: int = 8,
        pixel_fifo_depth: int | None = None,
        steady_state: bool = False,
        events: str = "compiled",
    ) -> None:
        self.scene, self.arch, self.plan = frame.scene, frame.arch, frame.plan
        if events not in ("compiled", "generators", "simpy"):
            raise ValueError(f"events: {events!r} (compiled, generators or simpy)")
        self.events = events
        arch, plan = frame.arch, frame.plan
        self.steady_state = steady_state
        skipping = arch.early_termination or arch.space_leaping
        if skipping and not self.models_skipping:
            raise NotAvailableError(
                f"{arch.name} skips beams (early ray termination, space leaping): its "
                "model needs each ray's termination step "
                "(models.machines.volumepro.vp1000_transaction)",
                key="--arch",
                allowed="cube4, cube4-teramac, volumepro500, em-cube, volumepro1000",
            )
        self.memory = require_pipeline_clock(parse_memory(arch.memory, source=arch.source), arch)
        self.words_per_voxel = words_per_voxel(frame.volume, self.memory)
        kp = plan.principal_axis
        a_ax, b_ax = _other_axes(plan)
        shape = plan.volume.shape
        self.kp, self.a_ax, self.b_ax = kp, a_ax, b_ax
        self.n_k, self.n_a, self.n_b = shape[kp], shape[a_ax], shape[b_ax]
        self.P = arch.pipelines
        self.C = -(-self.n_b // self.P)
        self.n_even = max(2, max(shape) + max(shape) % 2)
        self.n_u = -(-self.n_a // 2)  # mbbs per slab
        self.n_slabs = -(-self.n_k // 2)
        self.U = max(1, -(-self.n_u // max(1, int(groups))))  # mbbs per chunk
        self.bands = bands_of(plan, arch.section_width, self.n_a, a_ax, arch.source)
        if skipping and len(self.bands) > 1:
            raise NotAvailableError(
                "the transaction model does not section a machine that skips beams",
                source=arch.source,
                key="overheads.section_width",
                allowed="0 (no sectioning) with early termination or space leaping",
            )
        buffers = slab_buffers(arch, self.C)
        self.capacity_mbbs = buffers["slab_buffer_entries"] // (4 * self.C)
        depth = buffers["pixel_fifo_entries"]
        self.pixel_fifo_depth = depth if pixel_fifo_depth is None else pixel_fifo_depth
        self.forward = slice_direction(plan)
        self.row_pixels = max(1, plan.shape[1])
        self.slice_fifo = uses_slice_fifos(arch)
        self._windows: dict[int, tuple[int, int]] = {}  # _window_slabs' of this frame

    # ------------------------------------------------------------------ geometry

    def _window_slabs(self, j: int) -> tuple[int, int]:
        """Slabs holding voxel slices ``i0 - 1 .. i0 + 2`` of sample slice ``j`` (kept for
        the frame: rule 6's skips and the schedule both ask)."""
        if j in self._windows:
            return self._windows[j]
        n = self.n_k
        p = min(max(slice_position(self.plan, j, self.forward), 0.0), n - 1.0)
        i0 = min(math.floor(p), max(n - 2, 0))  # p finite, in 0 .. n - 1
        self._windows[j] = window = (max(i0 - 1, 0) // 2, min(i0 + 2, n - 1) // 2)
        return window

    def _all_windows(self, n_steps: int) -> None:
        """:meth:`_window_slabs` of every slice at once, kept: its rule on the plan's
        slice formula applied to an array (the same floats); shear-warp plans left out."""
        if self.plan.kind != "shear-warp" and n_steps > 0:
            n, p = self.n_k, slice_position(self.plan, np.arange(n_steps), self.forward)
            i0 = np.minimum(np.floor(np.clip(p, 0.0, n - 1.0)), max(n - 2, 0)).astype(np.int64)
            lo, hi = np.maximum(i0 - 1, 0) // 2, np.minimum(i0 + 2, n - 1) // 2
            self._windows.update(enumerate(zip(lo.tolist(), hi.tolist(), strict=True)))

    def _window_array(self, n_steps: int) -> np.ndarray:
        """int64 ``(n_steps, 2)``: :meth:`_window_slabs` of slices ``0 .. n_steps - 1``
        (those of :meth:`_all_windows` when it ran for them), kept for the frame."""
        kept = getattr(self, "_windows_kept", None)
        if kept is None or kept.shape[0] != n_steps:
            windows = [self._window_slabs(j) for j in range(n_steps)]
            kept = np.array(windows, dtype=np.int64).reshape(n_steps, 2)
            self._windows_kept = kept
        return kept

    def _schedule(self, n_steps: int):
        """Chunks in read order ``(band, slab, u_lo, u_hi)``; beam groups in processing
        order ``(band, j, clocks, last chunk needed)``; and for each chunk the last group
        that needs it (its buffer slot is freed when that group ends).

        With beam skipping (``self.skips``) a chunk holding no mini-block a live cell
        needs is not read, a group costs its rows' clocks (rule 6: clock groups of live
        rays), rows costing nothing need no chunk, and a slice whose every row is
        skipped keeps one empty group (its overhead and pixels still happen).
        """
        U, n_a, sk = self.U, self.n_a, self.skips
        slab_order = np.arange(self.n_slabs)[:: 1 if self.forward else -1]
        chunks, grids = [], []
        # Per slab and mbb, whether a mini-block of it is read.
        read = None if sk is None else sk.needed.any(axis=2)
        for bi, (a0, a1) in enumerate(self.bands):
            u0, u1 = max(a0 - 1, 0) // 2, min(a1 + 1, n_a - 1) // 2
            u_lo = np.arange(u0, u1 + 1, U)
            u_hi = np.minimum(u_lo + U - 1, u1)
            # Per slab and chunk of a slab, whether a mini-block of its mbbs is read.
            if read is None:
                kept = np.ones((self.n_slabs, u_lo.size), dtype=bool)
            else:
                kept = np.logical_or.reduceat(read[:, u0 : u1 + 1], u_lo - u0, axis=1)
            at, k = np.nonzero(kept[slab_order])  # in read order: slab after slab
            slabs = slab_order[at]
            # The band's chunk numbers by slab and chunk of a slab (-1: not read).
            grids.append(np.full(kept.shape, -1, np.int64))
            grids[bi][slabs, k] = np.arange(len(chunks), len(chunks) + k.size)
            chunks += zip(
                [bi] * k.size, slabs.tolist(), u_lo[k].tolist(), u_hi[k].tolist(), strict=True
            )
        if self.slice_fifo:  # rules 3', 5'
            return (chunks, *fifo_schedule(self, n_steps, chunks, chunk_index(grids)))
        from models.machines.volumepro.streams_kernel import beam_groups, live_spans  # numba

        windows = self._window_array(n_steps)
        parts, g = [], 0
        last = np.full(len(chunks), -1, dtype=np.int64)
        for bi, (a0, a1) in enumerate(self.bands):
            r0 = np.arange(a0, a1, 2 * U, dtype=np.int64)
            r1 = np.minimum(r0 + 2 * U, a1)
            if sk is None:  # every row: its span's clocks, rows r0 .. r1 - 1
                spans = tuple(
                    np.ascontiguousarray(np.broadcast_to(v, (n_steps, r0.size)))
                    for v in ((r1 - r0) * self.C, r0, r1 - 1)
                )
            else:  # per slice and span: clocks, first and last live row
                spans = live_spans(sk.cost[:n_steps], r0, r1)
            out = np.empty((n_steps * (r0.size + 1), 4), dtype=np.int64)
            u0 = max(a0 - 1, 0) // 2
            dims = (n_a, u0, U)
            end = beam_groups(grids[bi], windows.reshape(-1, 2), spans, dims, bi, g, out, last)
            parts.append(out[: end - g])
            g = end
        self._group_array = np.concatenate(parts)  # the compiled event loop's groups
        groups = list(map(tuple, self._group_array.tolist()))
        return chunks, groups, last

    # ------------------------------------------------------------------ frame

    def run(self) -> TxnTiming:
        """Simulate the frame; return its cycles and the event model's counters."""
        start = time.perf_counter()
        samples, finishing = slice_loads(self.plan)
        n_steps = len(samples)
        sk = self.skips
        if sk is not None:
            samples = sk.live  # samples of live rays: what the lanes work on (rule 6)
        # Clocks of each slice's beams (the stretch's reference): n_a C, less when skipping.
        beam_clocks = np.full(n_steps, self.n_a * self.C) if sk is None else sk.cost.sum(axis=1)
        # Samples of each slice's busiest pipeline (a slice lasts at least that long),
        # counted lane by lane: rays denser than voxels load the lanes unevenly.  A
        # shear-warp plan has one ray per voxel column, spread evenly by the skew.
        if sk is not None:
            busiest = sk.busiest  # live samples only (rule 6)
        elif self.plan.kind == "shear-image":
            busiest = busiest_lanes(self.plan, self.P)
        else:
            busiest = -(-samples // self.P)
        by_band, parked = band_loads(self.plan, self.bands, self.n_a, finishing)
        chunks, groups, free_after = self._schedule(n_steps)
        cap = self.capacity_mbbs // self.U
        if cap <= 0:
            raise DeadlockError(
                f"input buffer: {self.capacity_mbbs} mini-block beams hold no chunk of {self.U}"
            )
        # Progress: slices simulated, of one frame (and two more back to back, steady state).
        self._slices_done = [0, n_steps * (3 if self.steady_state else 1)]
        stats, bus, reads = self._simulate(
            chunks, groups, free_after, cap, busiest, beam_clocks, by_band, parked, frames=1
        )
        M = self.memory.modules
        if self.slice_fifo:  # rule 8': a period's pixels leave from its start + latency
            latency = stream_latency(self.C)
            cycles = max(stats["pipe_end"], bus.end + latency)
        else:
            latency = pipeline_latency(self.C)
            cycles = max(stats["pipe_end"], bus.end) + latency
        # Counted straight from the controllers' logs (no schedule arrays built).
        sdram = SdramStats.combine([p.controller.stats() for p in reads.ports])
        reads.release()  # read: the next frame may reuse its arrays
        counters: dict[str, Any] = {k: int(v) for k, v in sdram.to_counters("memory.sdram").items()}
        counters.update(
            {
                "memory.bursts": int(sdram.bursts),
                # data-bus cycles of one module (the modules share the load evenly)
                "memory.busy_cycles": int(sdram.data_busy_cycles) // M,
                "memory.read_bytes": int(sdram.bursts) * 8 * 2,  # 8 16-bit words a burst
                "memory.mbb_reads": self._mbb_reads(chunks),
                "memory.stall_cycles": stats["stall"],
                "memory.buffer_full_cycles": stats["buffer_full"],
                "memory.slab_buffer_chunks": cap,
                "pipelines.busy_cycles": -(-int(samples.sum()) // self.P),
                "pipelines.stall_cycles": stats["stall"] + bus.stall_cycles,
                "pipelines.stretch_cycles": stats["stretch"],
                **bus.counters(stats["pipe_end"]),
                "section.count": len(self.bands),
                "section.parked_rays": int(parked.sum()),
                "section.overhead_cycles": stats["section"],
                "pipeline.latency_cycles": latency,
                "frame.cycles": cycles,
                "frame.samples": int(samples.sum()),
                "transaction.events": stats["events"] + bus.events,
                "transaction.granularity": f"{self.U} mbbs / {2 * self.U} beams",
                **self._skip_counters(),
                "transaction.timing_seconds": time.perf_counter() - start,
            }
        )
        if self.steady_state:  # rule 9: the cycles between two back-to-back frames' ends
            twice, _, reads = self._simulate(
                chunks, groups, free_after, cap, busiest, beam_clocks, by_band, parked, frames=2
            )
            reads.release()
            counters["frame.period_cycles"] = twice["pipe_ends"][1] - twice["pipe_ends"][0]
            counters["transaction.timing_seconds"] = time.perf_counter() - start
        return TxnTiming(int(cycles), counters)

    def _simulate(
        self, chunks, groups, free_after, cap, busiest, beam_clocks, by_band, parked, *, frames
    ):
        """Run the memory and the pipelines over ``frames`` identical frames back to back
        (:func:`models.machines.volumepro.pipeline_events.simulate`); returns the
        statistics, the pixel bus and the deferred reads."""
        loads = (busiest, beam_clocks, by_band, parked)
        return simulate(self, chunks, groups, free_after, cap, loads, frames=frames)

    def _mbb_reads(self, chunks) -> int:
        """Mini-block beams read: every mbb of a chunk, or with skipping those holding a
        mini-block that is read."""
        if self.skips is None:
            return sum(u_hi - u_lo + 1 for _, _, u_lo, u_hi in chunks)
        # Each band's chunks partition its mbbs slab by slab, and a chunk is dropped only
        # when none of its mbbs is read: the band's mbbs read, counted at once.
        read = self.skips.needed.any(axis=2)  # (slab, mbb): some mini-block of it is read
        n_a = self.n_a
        return sum(
            int(read[:, max(a0 - 1, 0) // 2 : min(a1 + 1, n_a - 1) // 2 + 1].sum())
            for a0, a1 in self.bands
        )

    def _skip_counters(self) -> dict[str, int]:
        """Rule 6's counters (beams and bursts skipped) when the machine skips."""
        sk = self.skips
        if sk is None:
            return {}
        processed = int((sk.cost > 0).sum())
        return {
            "memory.bursts_skipped": int(sk.needed.size - sk.needed.sum()),
            "pipeline.beams_processed": processed,
            "pipeline.beams_skipped": int(sk.cost.size - processed),
            "pipeline.beam_cycles": int(sk.cost.sum()),
            "ert.stopped_rays": sk.stopped_rays,
            "space_leaping.samples_leaped": sk.leaped,
        }


def _other_axes(plan: SamplePlan) -> tuple[int, int]:
    a_ax, b_ax = (ax for ax in range(3) if ax != plan.principal_axis)
    return a_ax, b_ax
