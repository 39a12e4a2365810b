"""Frame timing of the VolumePro-family machines: pipelines fed by SDRAM through an input buffer.

# Ref: docs/cycle.md "Timing rules (VolumePro family)"; architectures.md 9.1 (voxel memory
#      controller, burst scheduling) and 9.5 item 3 (cycles per frame from the mechanisms).

Two in-order processes meet at the input (slab) buffer:

* the **memory**: mini-block beams (*deliveries*) in read order, each a list of bursts per
  module, scheduled cycle-exactly by one :class:`hwsim.memory.SdramController` per module
  (row hits, misses, conflicts, refresh, CAS latency).  Delivery ``g`` may not issue its
  first burst before the buffer has room: the cycle delivery ``g - cap`` was freed.  It is
  *ready* after the last data beat of its last burst on any module.
* the **pipelines**: beams of ``C`` clocks in processing order.  A beam starts when the
  previous one has finished and its last needed delivery is ready (else the pipelines
  stall: ``memory.stall_cycles``).  After a slice's last beam come the slice's extra
  cycles (overhead, perspective stretch) and the pixel-bus FIFO (a full FIFO stalls).
  A delivery is freed when the last beam that needs it has finished.

When a beam waits for a delivery that cannot issue until that very beam (or a later one)
has finished, the buffer is too small for the machine to progress: :class:`DeadlockError`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hwsim.core.models import Schema
from hwsim.engine import Counters, DeadlockError, DrainFifo
from hwsim.memory import MemoryConfig, SdramController, SdramStats
from hwsim.spec.arch import ArchConfig
from models.machines.common.results import UNITS, Entries, buffer_table
from models.units import skew as skew_unit

__all__ = [
    "SlabBuffers",
    "SliceWork",
    "Delivery",
    "DeliveryTable",
    "FrameTiming",
    "pipeline_latency",
    "run_timing",
    "slab_buffers",
    "summarise_timing",
]


def pipeline_latency(beam_cycles: int) -> int:
    """A slab pipeline's latency in clocks, the same for every scene (the hardware is
    fixed, so every unit counts): address and de-skew (``skew.LATENCY``), beam alignment
    ``C + 1``, and every unit's ``LATENCY`` (docs/cycle.md, the VolumePro family)."""
    return skew_unit.LATENCY + int(beam_cycles) + 1 + sum(u.LATENCY for u in UNITS.values())


@dataclass
class Delivery:
    """One mini-block beam: per module, the ``(banks, rows)`` int64 arrays of its bursts."""

    bursts: list[tuple[np.ndarray, np.ndarray]]
    free_after: int = -1  # global beam index whose end frees it (set by the caller)


@dataclass
class DeliveryTable:
    """Every delivery of a frame in read order, compactly: module ``k``'s bursts of
    delivery ``g`` are ``banks[starts[k, g]:starts[k, g + 1]]`` (and ``rows``), each
    module's bursts contiguous (int32: 8 bytes a burst over a 512^3 frame's ~17 M);
    ``free_after[g]``: the global beam index whose end frees delivery ``g``."""

    banks: np.ndarray
    rows: np.ndarray
    starts: np.ndarray  # (M, G + 1) int64
    free_after: np.ndarray  # (G,) int64

    def __len__(self) -> int:
        return int(self.free_after.size)

    def bursts(self, k: int) -> int:
        """Bursts module ``k`` issues in the frame."""
        return int(self.starts[k, -1] - self.starts[k, 0])

    def as_list(self) -> list[Delivery]:
        """The deliveries one object each (the reference loop's form)."""
        s, M = self.starts, self.starts.shape[0]
        return [
            Delivery(
                [
                    (self.banks[s[k, g] : s[k, g + 1]], self.rows[s[k, g] : s[k, g + 1]])
                    for k in range(M)
                ],
                int(f),
            )
            for g, f in enumerate(self.free_after.tolist())
        ]

    def twice(self, beam_shift: int) -> DeliveryTable:
        """The same deliveries read again after this frame's (rule 9): a second frame
        whose beams come ``beam_shift`` later."""
        s, M = self.starts, self.starts.shape[0]
        parts = [slice(int(s[k, 0]), int(s[k, -1])) for k in range(M)]
        banks = np.concatenate([self.banks[p] for p in parts for _ in range(2)])
        rows = np.concatenate([self.rows[p] for p in parts for _ in range(2)])
        local = s - s[:, :1]  # each module's offsets from its first burst
        size = local[:, -1:]
        base = np.concatenate([[0], np.cumsum(2 * size[:, 0])[:-1]])[:, None]
        starts = np.concatenate([local, local[:, 1:] + size], axis=1) + base
        free = np.concatenate([self.free_after, self.free_after + beam_shift])
        return DeliveryTable(banks, rows, starts, free)


@dataclass
class SliceWork:
    """One sample slice of one section as the pipelines see it.

    ``needs``: per processed beam, the index of the last delivery it needs (-1: none);
    ``cycles``: per processed beam, its clocks (``C``, fewer when skipping, rule 6);
    ``extra``: cycles after the last beam (slice overhead, perspective stretch);
    ``pre``: stall cycles before the first beam (a section change);
    ``arrivals``: accumulators pushed into the pixel FIFO at the slice's end.
    """

    needs: np.ndarray
    cycles: np.ndarray
    extra: int = 0
    pre: int = 0
    arrivals: int = 0
    busy: np.ndarray | None = None


@dataclass
class FrameTiming:
    """Per-slice blocks (cycles, stall cycles) and the totals the counters report."""

    blocks: list[tuple[int, int]] = field(default_factory=list)
    beam_ends: np.ndarray | None = None
    beam_cycles: np.ndarray | None = None
    schedules: list = field(default_factory=list)
    end: int = 0
    memory_stall: int = 0
    pixel_stall: int = 0
    stats: list[SdramStats] = field(default_factory=list)


def run_timing(
    memory: MemoryConfig,
    table: DeliveryTable,
    slices: list[SliceWork],
    *,
    capacity: int,
    pixel_fifo: DrainFifo,
    counters: Counters,
    keep_schedules: bool = False,
    compiled: bool = True,
    keep_bursts: bool = True,
    deskew: int = 0,
) -> FrameTiming:
    """Run the pipelines and the memory of one frame (rules of docs/cycle.md).

    Parameters
    ----------
    memory : MemoryConfig
        Modules and device timing.
    table : DeliveryTable
        Mini-block beams in read order, ``free_after`` set.
    slices : list of SliceWork
        Processing order.
    capacity : int
        Input-buffer capacity in deliveries (>= 0).
    pixel_fifo : DrainFifo
    counters : Counters
    keep_schedules : bool
        Keep every module's per-burst schedule in ``schedules`` (a waveform needs them);
        otherwise only their ``stats``.
    compiled : bool
        Run the loop compiled (:mod:`models.machines.volumepro.timing_kernel`); False
        runs the reference loop below, one Python call per delivery and module.
    keep_bursts : bool
        False: ``table``'s per-burst banks and rows are dropped once the loop has played
        them (8 bytes a burst, before the schedules are summarised), for a caller that
        reads them no more.
    deskew : int
        Clocks from a delivery's last data beat to its first use (rule 3': the de-skew
        network's write into the slab buffer; 0 under rule 3).
    """
    dev = memory.sdram

    def make_controllers() -> list[SdramController]:
        made = [SdramController(dev) for _ in range(memory.modules)]
        if not compiled:  # the compiled loop sizes one stacked copy itself (no second)
            for k, ctl in enumerate(made):  # each module's requests, known up front
                ctl.reserve(table.bursts(k))
        return made

    tail = dev.cas_latency + dev.burst_cycles
    n_beams = sum(int(s.needs.size) for s in slices)
    ends = np.zeros(max(n_beams, 1), dtype=np.int64)
    ready = np.zeros(max(len(table), 1), dtype=np.int64)
    out = FrameTiming()
    if compiled:
        from models.machines.volumepro.timing_kernel import play  # imports numba

        controllers = play(
            table, slices, make_controllers, capacity=capacity, pixel_fifo=pixel_fifo,
            out=out, ends=ends, ready=ready, tail=tail, ratio=dev.clock_ratio, deskew=deskew,
        )  # fmt: skip
    else:
        controllers = make_controllers()
        _reference_loop(
            table.as_list(), slices, controllers, capacity, pixel_fifo, out, ends, ready, deskew
        )
    if not keep_bursts:
        table.banks = table.rows = None
    return summarise_timing(out, controllers, ends[:n_beams], slices, keep_schedules)


def summarise_timing(
    out: FrameTiming, controllers: list, beam_ends: np.ndarray, slices, keep_schedules: bool
) -> FrameTiming:
    """``out`` once the loop has played: each module's schedule statistics (and, with
    ``keep_schedules``, the schedules), the beams' ends and clocks."""
    # One module's schedule at a time, each controller dropped once read: at 512^3 a
    # schedule holds ~40 bytes per burst and the frame ~17 M bursts.  The per-burst
    # arrays are kept only for a waveform.
    for k, ctl in enumerate(controllers):
        sched = ctl.schedule(copy=keep_schedules)
        controllers[k] = None
        out.stats.append(sched.stats)
        if keep_schedules:
            out.schedules.append(sched)
        del sched, ctl
    out.beam_ends = beam_ends
    out.beam_cycles = np.concatenate([s.cycles for s in slices]) if slices else beam_ends[:0]
    return out


def _reference_loop(
    deliveries, slices, controllers, capacity, pixel_fifo, out, ends, ready, deskew
):
    """The frame's beams and deliveries one Python step at a time (the compiled loop's
    reference)."""
    dev = controllers[0].cfg
    tail = dev.cas_latency + dev.burst_cycles
    state = {"g": 0, "bi": 0}

    def deliver() -> None:
        g = state["g"]
        if g >= len(deliveries):
            raise DeadlockError(f"a beam needs delivery {g}, which the memory never reads")
        earliest = 0
        if g >= capacity:
            f = deliveries[g - capacity].free_after
            if f >= state["bi"]:
                raise DeadlockError(
                    f"input buffer: {capacity} mini-block beams cannot hold the sample "
                    f"window; delivery {g} waits for beam {f} to free a slot while the "
                    f"pipelines wait for it at beam {state['bi']}"
                )
            earliest = int(ends[f])
        e_mem = int(np.ceil(earliest * dev.clock_ratio))
        last = 0
        for ctl, (banks, rows) in zip(controllers, deliveries[g].bursts, strict=True):
            if not len(banks):
                continue
            # The controller's own loop (``issue_many`` without re-validating arrays the
            # layout built): any split of a stream gives the batch schedule.
            arrive = np.zeros(len(banks), dtype=np.int64)
            arrive[0] = e_mem
            ctl._run(banks, rows, arrive)
            last = max(last, int(ctl.reads[-1]) + tail)
        ready[g] = int(np.ceil(last / dev.clock_ratio)) + deskew
        state["g"] = g + 1

    t = 0
    for work in slices:
        start_block = t
        t += work.pre
        stall = 0
        for need, clocks in zip(work.needs.tolist(), work.cycles.tolist(), strict=True):
            while need >= state["g"]:
                deliver()
            begin = t if need < 0 or ready[need] <= t else int(ready[need])
            stall += begin - t
            t = begin + clocks
            ends[state["bi"]] = t
            state["bi"] += 1
        t += work.extra
        pix = pixel_fifo.advance(t - start_block, work.arrivals, start_block)
        t += pix
        out.memory_stall += stall
        out.pixel_stall += pix
        out.blocks.append((t - start_block, stall + pix + work.pre))
    while state["g"] < len(deliveries):  # reads no beam waits for (none by construction)
        deliver()
    out.end = t


class SlabBuffers(Schema):
    """``[buffers]`` of a VolumePro-family machine: entries per pipeline; absent, sized
    for ``limits.max_volume`` (:func:`slab_buffers`)."""

    slab_buffer_entries: Entries | None = None
    beam_fifo_entries: Entries | None = None
    pixel_fifo_entries: Entries | None = None


def slab_buffers(arch: ArchConfig, C: int) -> dict[str, int]:
    """A VolumePro-family machine's capacities per pipeline (``[buffers]``, entries),
    checked against a volume of ``C`` clocks per beam.  One copy for the cycle and
    transaction models.

    ``slab_buffer_entries`` defaults to ``8 n ceil(n / P)`` for ``n = max(max_volume)``:
    four mini-block slabs -- the sample window (voxel slices ``i0 - 1 .. i0 + 2``, up to
    three slabs) and one slab read ahead.
    """
    n_max = max(arch.max_volume)
    c_max = -(-n_max // arch.pipelines)
    defaults = {
        "slab_buffer_entries": 8 * n_max * c_max,
        "beam_fifo_entries": c_max + 1,
        "pixel_fifo_entries": n_max * n_max,
    }
    return buffer_table(arch, SlabBuffers, defaults, {"beam_fifo_entries": C + 1})
