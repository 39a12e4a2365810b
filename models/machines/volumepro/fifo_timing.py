"""The slice-FIFO rules 3', 5', 8' of the VolumePro 500's and EM-Cube's cycle rung: the
voxels stream through slice and beam delay FIFOs, each read once, one slice ahead of its
samples (issue 35).

# Ref: architectures.md section 1.3 items 2, 4-5 (Cube-4: slice by slice, beam by beam,
#      one-beam and one-slice delay FIFOs give the neighbours), 2 (EM-Cube derived from
#      Cube-4), 3 (lineage Cube-4 -> EM-Cube -> VolumePro [V]; mini-block bursts and the
#      de-skewing network, US 6,266,733; sectioning US 6,262,740; z-supersampling), 9.1
#      (slice/beam delay FIFOs; de-skew a 1-cycle crossbar [I]), 9.2 (voxel slice delay
#      N^2/P entries per pipeline; with sections S N); docs/cycle.md (rules 3', 5', 8').

:func:`fifo_work` turns the data pass's record into the pipelines' *periods* (one pass
over a section's rows, a beam of ``C`` clocks a row) for
:func:`models.machines.volumepro.slab_timing.run_timing`:

3'. the read stream runs ahead of the samples: a sample slice's period reads the voxel
    slice its samples reach furthest (``reach``: the upper interpolation tap, plus one for
    the central difference's next sample) if it is not read yet; slices it needs before
    that are read by periods of their own, without samples (the first slice's priming
    period; two at a sampling factor below 1).  Beam ``a`` of a period waits only for
    the mini-block beam holding row ``a`` of the slice it reads, usable one clock after
    its last data beat (the de-skew's write into the slab buffer, ``DESKEW_WRITE``).  A
    section's periods read its rows ``a0 - 1 .. a1 + 1`` (each voxel row the section's
    samples use), a beam each.
5'. a mini-block beam is freed at the end of the last beam reading one of its rows.
8'. (:func:`fifo_end`) each ray is pushed into the pixel FIFO when its last sample of a
    section is written back, :func:`stream_latency` after the slot of the beam that read
    its row, the bus popping one pixel per clock; a full FIFO freezes the pipelines until
    the bus pops (the freeze adds its clocks to the frame).  A wait for memory holds the
    whole top (pipelines, FIFO, bus), so pushes and pops run on the wait-free clock and
    the frame adds the waits before each; the frame ends with the last pop or the last
    beam, whichever is later.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.engine import DeadlockError
from models.machines.common.results import UNITS
from models.machines.volumepro.slab_timing import SliceWork
from models.units import skew as skew_unit

__all__ = [
    "DESKEW_WRITE",
    "FifoPlan",
    "FifoTiming",
    "fifo_end",
    "fifo_work",
    "slice_fifo_timing",
    "stream_latency",
    "uses_slice_fifos",
]

#: Clocks from a mini-block beam's last data beat to the slab buffer's read of it: the
#: de-skew network's registered write (architectures.md 9.1: a 1-cycle crossbar [I]).
DESKEW_WRITE = 1

#: The units between the slab buffer and the pixel FIFO (Cube-4's, in dataflow order).
#: The crop unit (VolumePro 500 [V]) decides from the sample's position, known at its
#: slot, so it runs beside interpolation and gradients and adds no clock to the stream.
STREAM_UNITS = ("interp", "gradient", "classify", "shade", "composite")


def uses_slice_fifos(arch) -> bool:
    """Whether a VolumePro-family machine's published structure is Cube-4's slice and beam
    delay FIFOs: the shear-warp machines (EM-Cube and VolumePro 500, Cube-4's descendants
    computing gradients from interpolated samples, architectures.md 2-3).  The VolumePro
    1000 (shear-image order, gradients at voxels, early ray termination deciding which
    mini-blocks are read, section 4) keeps the windowed rules 3, 5, 8, and so does a
    shear-warp file that turns skipping on (rule 6 decides reads per sample window,
    which a stream reading every voxel once has not)."""
    skipping = arch.early_termination or arch.space_leaping
    return arch.order == "shear-warp" and not skipping


def stream_latency(beam_cycles: int) -> int:
    """Clocks from a slot's read to the first clock its ray's pixel can leave the pixel
    FIFO (the structure of Cube-4's rule 5, ``models.machines.cube4.timing.cube4_latency``;
    the machines may not import each other): address and de-skew (``skew.LATENCY``), the
    slice-buffer read 1, beam alignment ``C + 1``, gradient look-ahead ``C``, the units'
    ``LATENCY`` (:data:`STREAM_UNITS`) and the FIFO's write 1: ``2 C + 56``."""
    C = int(beam_cycles)
    units = sum(UNITS[u].LATENCY for u in STREAM_UNITS)
    return skew_unit.LATENCY + 1 + (C + 1) + C + units + 1


def reach(m, j: int) -> int:
    """Rule 3': the voxel slice (processing order) furthest along that sample slice ``j``
    uses: its upper interpolation tap (the lower one at a weight of 0), plus one for the
    central difference's next sample (at the same weight), clipped to the volume."""
    i0, i1, w = m.k_taps(np.array([m.slice_position(j)]))
    n = m.n_kp
    if m.forward:
        return min((i1 if w > 0 else i0) + 1, n - 1)
    return n - 1 - max((i0 if w < m.weight_one else i1) - 1, 0)


@dataclass
class FifoPlan:
    """Where each sample slice's period sits: ``period[r]`` the index of record ``r``'s
    period among the slices, ``first_row[k]`` the first row slice ``k`` reads."""

    period: np.ndarray
    first_row: np.ndarray


def fifo_work(m, records, sections, parked_counts, index, n_deliveries: int):
    """Rules 3' and 5': the pipelines' periods (:class:`SliceWork`), each delivery's
    ``free_after`` and the :class:`FifoPlan`; ``index[s, slab, u]`` the delivery of
    mini-block beam ``u`` of a slab in section ``s``."""
    if m.skipping:
        raise InputError(
            f"{m.arch.name}: early ray termination and space leaping are not timed on the "
            "slice-FIFO structure (each voxel streams through once)",
            source=m.arch.source,
            key="features.early_termination",
            allowed="false with features.space_leaping false on a shear-warp machine",
        )
    C, n_kp = m.C, m.n_kp
    free_after = np.full(n_deliveries, -1, dtype=np.int64)
    slices: list[SliceWork] = []
    period = np.zeros(len(records), dtype=np.int64)
    first_row: list[int] = []
    beam, section, read, pre = 0, -1, 0, 0

    def emit(rows, p, extra, busy):
        nonlocal beam, pre
        if p < 0:
            needs = np.full(rows.size, -1, dtype=np.int64)
        else:
            q = p if m.forward else n_kp - 1 - p
            needs = index[section, q // 2, rows // 2]
            ok = needs >= 0
            np.maximum.at(free_after, needs[ok], beam + np.flatnonzero(ok))
        cycles = np.full(rows.size, C, dtype=np.int64)
        slices.append(SliceWork(needs, cycles, extra=extra, pre=pre, busy=busy))
        first_row.append(int(rows[0]))
        beam += rows.size
        pre = 0

    idle = np.zeros(m.P, dtype=np.int64)
    for r, rec in enumerate(records):
        if rec.section != section:
            if section >= 0:
                pre = m.arch.section_overhead_cycles + parked_counts[section]
            section, read = rec.section, 0
            a0, a1 = sections[section]
            rows = np.arange(max(a0 - 1, 0), min(a1 + 1, m.n_a - 1) + 1)
        while read < rec.reach:  # slices needed before this one's: periods of their own
            emit(rows, read, 0, idle)
            read += 1
        own = read if read == rec.reach else -1
        read += own >= 0
        stretch = max(0, int(rec.busy.max(initial=0)) - rows.size * C)
        period[r] = len(slices)
        emit(rows, own, m.arch.slice_overhead_cycles + stretch, rec.busy)
    return slices, free_after, FifoPlan(period, np.array(first_row, dtype=np.int64))


def _wait_free(slices) -> tuple[np.ndarray, np.ndarray, int]:
    """Each period's first beam clock and each beam's first clock on the wait-free clock
    (no memory wait), and the clock after the last period."""
    spans = np.array([s.pre + int(s.cycles.sum()) + s.extra for s in slices], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(spans)])
    begins = [starts[k] + s.pre + np.cumsum(s.cycles) - s.cycles for k, s in enumerate(slices)]
    flat = np.concatenate(begins) if begins else np.zeros(0, dtype=np.int64)
    return starts[:-1] + [s.pre for s in slices], flat, int(starts[-1])


@dataclass
class PixelBus:
    """Rule 8' played: the frame's end on the real clock, the freeze, the bus's tail past
    the last beam and what the bus counters report."""

    end: int
    freeze: int
    drain: int
    pushed: int
    max_occupancy: int


def fifo_end(m, plan: FifoPlan, pushes, slices, timing, depth: int, frames: int = 1):
    """Rule 8': the end of each of ``frames`` frames played back to back (``slices`` and
    ``timing`` hold them all, ``pushes`` = ``(record, a, b)`` arrays of one frame).
    Returns one :class:`PixelBus` per frame (its ``end`` on the real clock)."""
    rec, a, b = pushes
    if depth <= 0 and rec.size:
        raise DeadlockError(
            f"pixel_bus.fifo: depth {depth} can never accept a pixel; the compositors wait forever"
        )
    period_start, beam_sf, total = _wait_free(slices)
    per_frame = len(slices) // frames
    lat = stream_latency(m.C)
    one = period_start[plan.period[rec]] + (a - plan.first_row[plan.period[rec]]) * m.C
    one = one + b // m.P + lat - 1
    frame_sf = [int(period_start[f * per_frame] - slices[f * per_frame].pre) for f in range(frames)]
    frame_sf.append(total)
    # The memory's waits before each beam: the real clock less the wait-free one.
    real_begin = timing.beam_ends - timing.beam_cycles
    held = real_begin - beam_sf
    push = np.concatenate([one + frame_sf[f] for f in range(frames)])
    order = np.argsort(push, kind="stable")
    push, frame = push[order], np.repeat(np.arange(frames), one.size)[order]
    pops, frozen, peak = _pops(push, depth)
    out = []
    for f in range(frames):
        mine = np.flatnonzero(frame == f)
        freeze = int(frozen[mine[-1]]) if mine.size else 0
        beams_end = frame_sf[f + 1] + freeze
        last = max(int(pops[mine[-1]]) + 1, beams_end) if mine.size else beams_end
        i = int(np.searchsorted(beam_sf, last - freeze, side="right")) - 1
        waits = int(held[i]) if i >= 0 else 0
        out.append(PixelBus(last + waits, freeze, max(0, last - beams_end), mine.size, peak))
    return out


def _pops(push: np.ndarray, depth: int):
    """Rule 8' on pushes sorted by clock: each entry's pop clock (one a clock, in order;
    an entry pushed in a clock leaves the next at the earliest), the freeze so far after
    each push, and the FIFO's peak occupancy.  Closed form while the FIFO never fills
    (``pop_i = i + max_k<=i (push_k + 1 - k)``); else played entry by entry, the
    pipelines frozen while it is full."""
    n = push.size
    i = np.arange(n)
    pops = i + np.maximum.accumulate(push + 1 - i) if n else push.copy()
    waiting = i + 1 - np.searchsorted(pops, push, side="right")
    if not n or int(waiting.max()) <= depth:
        return pops, np.zeros(n, dtype=np.int64), int(waiting.max(initial=0))
    frozen = np.zeros(n, dtype=np.int64)
    pop, freeze, queue, peak = -1, 0, deque(), 0
    for k, p in enumerate(push.tolist()):
        e = p + freeze
        while queue and queue[0] <= e:
            queue.popleft()
        if len(queue) >= depth:  # full: the pipelines freeze until the bus pops
            freeze += queue[0] - e
            e = queue.popleft()
        pop = max(pop + 1, e + 1)
        queue.append(pop)
        pops[k], frozen[k] = pop, freeze
        peak = max(peak, len(queue))
    return pops, frozen, peak


@dataclass
class FifoTiming:
    """A frame's cycles, the clocks the pipelines waited for memory, and each beam's
    first clock (the rung's own, :func:`slice_fifo_timing`)."""

    cycles: int
    stall_cycles: int
    beam_begins: np.ndarray


def slice_fifo_timing(machine) -> FifoTiming:
    """Run ``machine`` (a :class:`~models.machines.volumepro.cycle.SlabMachine` on a
    slice-FIFO machine, built, not run) and return its timing: the cycle rung's frame."""
    result = machine.run()
    timing = machine.timing
    return FifoTiming(
        result.cycles,
        int(result.counters["memory.stall_cycles"]),
        timing.beam_ends - timing.beam_cycles,
    )
