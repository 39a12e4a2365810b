"""The timing pass of the VolumePro-family model: from the data pass's record to the clock.

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rules 1-9; architectures.md 9.1
#      (voxel memory controller, burst scheduling).

:func:`timing_inputs` turns what each sample slice did (:class:`SliceRecord`) into the
memory's deliveries (mini-block beams to read, in order, with the bursts each module
issues) and the pipelines' work (beams, their clocks and the deliveries they wait for),
which :func:`models.machines.volumepro.slab_timing.run_timing` plays out;
:func:`frame_period` plays two frames back to back (rule 9) and :func:`record_trace`
writes the waveform.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from hwsim.engine import Counters, DrainFifo
from hwsim.memory import SdramStats
from hwsim.memory.sdram_trace import command_trace, record_commands
from models.machines.volumepro.fifo_timing import (
    DESKEW_WRITE,
    fifo_end,
    fifo_work,
    uses_slice_fifos,
)
from models.machines.volumepro.skips_kernel import beam_needs
from models.machines.volumepro.slab_timing import DeliveryTable, SliceWork, run_timing

if TYPE_CHECKING:
    from models.machines.volumepro.cycle import SlabMachine

__all__ = [
    "SliceRecord",
    "count_timing",
    "deliveries_read",
    "timing_inputs",
    "frame_period",
    "mini_blocks_read",
    "record_trace",
]


@dataclass
class SliceRecord:
    """What one sample slice of one section did (the data pass's record for timing)."""

    section: int
    window: tuple[int, int]  # voxel slices [lo, hi] the slice's beams read
    cost: np.ndarray | None  # clocks of each row's beam (None: C for every row of the section)
    busy: np.ndarray  # samples per lane
    arrivals: int  # accumulators pushed into the pixel FIFO at its end (rule 8)
    reach: int = -1  # rule 3': the voxel slice its samples reach furthest (processing order)


def timing_inputs(m: SlabMachine, records, sections, parked_counts, needed):
    """Deliveries (mini-block beams to read, in order: a :class:`DeliveryTable`) and the
    pipelines' slices (and, on a slice-FIFO machine, the :class:`FifoPlan` of its periods,
    else None)."""
    burst_banks, burst_rows, starts, index = deliveries_read(m, sections, needed)
    n_deliveries = starts.shape[1] - 1
    if uses_slice_fifos(m.arch):  # rules 3', 5'
        slices, free_after, plan = fifo_work(
            m, records, sections, parked_counts, index, n_deliveries
        )
        return DeliveryTable(burst_banks, burst_rows, starts, free_after), slices, plan
    free_after = np.full(n_deliveries, -1, dtype=np.int64)
    slices: list[SliceWork] = []
    beam = 0
    prev_section = 0
    for rec in records:
        a0, a1 = sections[rec.section]
        rows = np.arange(a0, a1)
        if rec.cost is None:
            cycles = np.full(rows.size, m.C, dtype=np.int64)
        else:
            cycles = rec.cost[a0:a1]
            rows, cycles = rows[cycles > 0], cycles[cycles > 0]
        need = np.full(rows.size, -1, dtype=np.int64)
        s0, s1 = rec.window[0] // 2, rec.window[1] // 2
        if m.be.compiled:  # the same reads, one compiled loop (skips_kernel.beam_needs)
            beam_needs(index[rec.section], rows, s0, s1, m.n_a, beam, need, free_after)
        else:
            _beam_needs(index[rec.section], rows, s0, s1, m.n_a, beam, need, free_after)
        beam += rows.size
        pre = 0
        if rec.section != prev_section:
            pre = m.arch.section_overhead_cycles + parked_counts[prev_section]
            prev_section = rec.section
        stretch = max(0, int(rec.busy.max(initial=0)) - int(cycles.sum()))
        slices.append(
            SliceWork(
                need,
                cycles,
                extra=m.arch.slice_overhead_cycles + stretch,
                pre=pre,
                arrivals=rec.arrivals,
                busy=rec.busy,
            )
        )
    return DeliveryTable(burst_banks, burst_rows, starts, free_after), slices, None


def deliveries_read(m: SlabMachine, sections, needed):
    """The frame's deliveries in read order (section by section, slab by slab in
    processing order, the beams of a slab whose mini-blocks ``needed`` marks): each
    module's bursts' banks and rows (int32, module after module), the :class:`DeliveryTable`
    ``starts`` and ``index[s, slab, u]``, the delivery of mini-block beam ``u`` of a slab
    in section ``s`` (-1: not read).  Reads ``needed`` and the layout only."""
    n_slabs = needed.shape[1]
    slab_order = range(n_slabs) if m.forward else range(n_slabs - 1, -1, -1)
    index = np.full(needed.shape[:3], -1, dtype=np.int64)
    M = m.memory_cfg.modules
    chunks: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in range(M)]
    counts: list[np.ndarray] = []  # per slab: (M, beams) bursts of each beam per module
    n_deliveries = 0
    for si in range(len(sections)):
        for slab in slab_order:
            us = np.flatnonzero(needed[si, slab].any(axis=1))
            if not us.size:
                continue
            module, bank, row = m.memory.slab_bursts(m.kp, slab)
            per_block = m.memory.words_per_voxel  # bursts per mini-block
            keep = np.repeat(needed[si, slab, us], per_block, axis=1)
            module, bank, row = module[us], bank[us], row[us]
            # Each module's kept bursts of every beam u at once, in the beams' order.
            count = np.zeros((M, us.size), dtype=np.int64)
            if m.be.compiled:  # one compiled pass (_module_bursts), the same arrays
                banks, rows, ends = _module_bursts(module, bank, row, keep, count)
                for k in range(M):
                    chunks[k].append((banks[ends[k] : ends[k + 1]], rows[ends[k] : ends[k + 1]]))
            else:
                for k in range(M):
                    sel = (module == k) & keep
                    count[k] = sel.sum(axis=1)
                    chunks[k].append((bank[sel].astype(np.int32), row[sel].astype(np.int32)))
            counts.append(count)
            index[si, slab, us] = n_deliveries + np.arange(us.size)
            n_deliveries += us.size
    per = np.concatenate(counts, axis=1) if counts else np.zeros((M, 0), dtype=np.int64)
    sizes = per.sum(axis=1)
    starts = np.zeros((M, n_deliveries + 1), dtype=np.int64)
    np.cumsum(per, axis=1, out=starts[:, 1:])
    starts += np.concatenate([[0], np.cumsum(sizes)[:-1]])[:, None]
    empty = np.zeros(0, dtype=np.int32)
    burst_banks = np.concatenate([b for k in range(M) for b, _ in chunks[k]] or [empty])
    burst_rows = np.concatenate([r for k in range(M) for _, r in chunks[k]] or [empty])
    return burst_banks, burst_rows, starts, index


def count_timing(m: SlabMachine, timing, deliveries, slices, frame, needed, fifo: bool) -> None:
    """The frame's memory, pipeline and section counters from its timing pass: ``frame =
    (records, sections, parked_counts)`` of the data pass, ``fifo``: slice-FIFO periods."""
    c, (records, sections, parked_counts) = m.counters, frame
    sdram = SdramStats.combine(timing.stats)
    for key, value in sdram.to_counters("memory.sdram").items():
        c.set(key, int(value))
    for k, stats in enumerate(timing.stats):
        c.set(f"memory.module[{k}].bursts", stats.bursts)
        c.set(f"memory.module[{k}].busy_cycles", stats.data_busy_cycles)
    n_beams = sum(s.needs.size for s in slices)
    all_beams = sum(sections[r.section][1] - sections[r.section][0] for r in records)
    if fifo:  # rule 3': every period's beams run (and the halo rows')
        all_beams = n_beams
    c.set("memory.mbb_reads", len(deliveries))
    c.set("memory.bursts_skipped", int(needed.size - needed.sum()))
    c.set("memory.bursts", sdram.bursts)
    c.set("memory.stall_cycles", timing.memory_stall)
    c.set("memory.buffer_full_cycles", sdram.stall_arrival_cycles)
    c.set("pipeline.beams_processed", n_beams)
    c.set("pipeline.beams_skipped", all_beams - n_beams)
    c.set("pipeline.beam_cycles", int(sum(int(s.cycles.sum()) for s in slices)))
    c.set(
        "pipeline.slice_stretch_cycles",
        sum(s.extra for s in slices) - len(slices) * m.arch.slice_overhead_cycles,
    )
    c.set("section.count", len(sections))
    c.set("section.parked_rays", sum(parked_counts))
    c.set("section.reload_cycles", sum(parked_counts[:-1]))
    c.set("section.overhead_cycles", (len(sections) - 1) * m.arch.section_overhead_cycles)


@numba.njit(cache=True, nogil=True)
def _module_bursts(module, bank, row, keep, count):  # pragma: no cover - compiled
    """The kept bursts (``keep``) of a slab's beams ``(u, burst)`` split by module: their
    banks and rows as int32, module by module (module ``k``'s from ``ends[k]`` to
    ``ends[k + 1]``), each in the beams' row-major order, and ``count[k, u]`` the bursts
    of beam ``u`` on module ``k`` (zeros in): ``bank[(module == k) & keep]`` for each
    ``k`` in one pass."""
    n_u, n_b = module.shape
    M = count.shape[0]
    for u in range(n_u):
        for i in range(n_b):
            if keep[u, i]:
                count[module[u, i], u] += 1
    ends = np.zeros(M + 1, dtype=np.int64)
    for k in range(M):
        ends[k + 1] = ends[k] + count[k].sum()
    banks = np.empty(ends[M], dtype=np.int32)
    rows = np.empty(ends[M], dtype=np.int32)
    fill = ends[:M].copy()
    for u in range(n_u):
        for i in range(n_b):
            if keep[u, i]:
                k = module[u, i]
                banks[fill[k]] = bank[u, i]
                rows[fill[k]] = row[u, i]
                fill[k] += 1
    return banks, rows, ends


def _beam_needs(index, rows, s0, s1, n_a, first, need, free_after) -> None:
    """:func:`skips_kernel.beam_needs` in NumPy (the reference): ``need`` and
    ``free_after`` updated in place."""
    u_lo = np.maximum(rows - 1, 0) // 2
    u_hi = np.minimum(rows + 2, n_a - 1) // 2
    slabs = np.arange(s0, s1 + 1)
    ids = np.arange(first, first + rows.size)
    for d in range(3):
        u = np.minimum(u_lo + d, u_hi)
        got = index[np.ix_(slabs, u)]  # (slabs, beams)
        need[:] = np.maximum(need, got.max(axis=0, initial=-1))
        for row_ids in got:
            ok = row_ids >= 0
            np.maximum.at(free_after, row_ids[ok], ids[ok])


def record_trace(m: SlabMachine, timing, deliveries: DeliveryTable) -> None:
    """VCD: each SDRAM module's data bus (``memory[m]/o__valid``, pipeline clocks), its
    command bus (``memory[m].sdram``: ``cmd``, ``ba``, ``a`` as the device's pins, and a
    count of commands; :func:`hwsim.memory.sdram_trace.record_commands`, when the memory
    runs at the pipeline clock) and the pipelines' beams (``pipelines/i__valid``: a beam
    is being processed)."""
    sdram = m.memory_cfg.sdram
    ratio = sdram.clock_ratio

    def ranges(first: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        edges = np.concatenate([first, end])
        values = np.concatenate([np.ones(first.size), np.zeros(end.size)]).astype(np.int64)
        # A range starting where the previous one ended keeps the signal high.
        keep = ~np.isin(end, first)
        edges = np.concatenate([first, end[keep]])
        values = values[np.concatenate([np.ones(first.size, bool), keep])]
        return edges, values

    for k, sched in enumerate(timing.schedules):
        first = np.floor(sched.data_first / ratio).astype(np.int64)
        end = np.ceil(sched.data_end / ratio).astype(np.int64)
        m.trace.record(f"memory[{k}]", "o__valid", 1, *ranges(first, end))
        if ratio == 1.0:  # one VCD time unit a memory clock
            lo, hi = int(deliveries.starts[k, 0]), int(deliveries.starts[k, -1])
            banks, rows = deliveries.banks[lo:hi], deliveries.rows[lo:hi]
            commands = command_trace(sdram, sched, banks, rows)
            record_commands(m.trace, f"memory[{k}].sdram", commands)
    ends = timing.beam_ends
    starts = ends - timing.beam_cycles
    m.trace.record("pipelines", "i__valid", 1, *ranges(starts, ends))


def frame_period(m: SlabMachine, deliveries, slices, capacity: int, fifo=None) -> int:
    """Cycles between the ends of two frames rendered back to back (the continuous frame
    rate): the same memory controllers and pixel FIFO carry on into a second frame, so
    its fill overlaps the first frame's last slices and the first frame's pixels drain
    while the second is processed.  ``fifo``: ``(plan, pushes, depth)`` on a slice-FIFO
    machine (rule 8' ends each frame), else None (rule 8)."""
    n_beams = sum(s.needs.size for s in slices)
    n_del = len(deliveries)
    shifted = [
        dataclasses.replace(s, needs=np.where(s.needs >= 0, s.needs + n_del, -1)) for s in slices
    ]
    fifo_depth = fifo[2] if fifo else m.capacity["pixel_fifo_entries"]
    timing = run_timing(
        m.memory_cfg,
        deliveries.twice(n_beams),
        slices + shifted,
        capacity=capacity,
        pixel_fifo=DrainFifo("pixel_bus.fifo", fifo_depth),
        counters=Counters(),
        compiled=m.be.compiled,
        deskew=DESKEW_WRITE if fifo else 0,
    )
    if fifo:
        first, second = fifo_end(m, fifo[0], fifo[1], slices + shifted, timing, fifo[2], 2)
        return second.end - first.end
    first = sum(b[0] for b in timing.blocks[: len(slices)])
    return int(timing.end - first)


def mini_blocks_read(cells: np.ndarray) -> np.ndarray:
    """Rule 6's reads: the mini-blocks ``(ceil(n_a / 2), ceil(n_b / 2))`` of a slab's
    plane holding a voxel that some marked cell reads; cell ``(a, b)`` reads voxel rows
    ``a - 1 .. a + 2`` and columns ``b - 1 .. b + 2`` (corners and gradient neighbours).
    Shared by the cycle machine and the VolumePro 1000 transaction model."""
    n_a, n_b = cells.shape
    rows = cells.copy()  # voxel rows a - 1 .. a + 2 of each marked cell
    rows[:-1] |= cells[1:]
    rows[1:] |= cells[:-1]
    rows[2:] |= cells[:-2]
    pad = np.zeros((-(-n_a // 2) * 2, -(-n_b // 2) * 2), dtype=bool)
    voxels = pad[:n_a, :n_b]  # then columns b - 1 .. b + 2, into the even-sized plane
    voxels[:] = rows
    voxels[:, :-1] |= rows[:, 1:]
    voxels[:, 1:] |= rows[:, :-1]
    voxels[:, 2:] |= rows[:, :-2]
    pairs = pad[0::2] | pad[1::2]  # the two voxel rows of a mini-block, then its columns
    return pairs[:, 0::2] | pairs[:, 1::2]
