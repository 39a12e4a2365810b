"""The VolumePro 500's frame timing under the published slice-FIFO structure: a candidate
for the cycle rung's rules 3, 5 and 8, checked against the vg500 RTL top (issue 35).

# Ref: architectures.md section 3 (lineage Cube-4 -> EM-Cube -> VolumePro [V]; mini-block
#      bursts and the de-skewing network, US 6,266,733), 9.1 (slice/beam delay FIFOs give
#      the y and z neighbours: "one-beam and one-slice delays"; de-skew a 1-cycle crossbar
#      [I]), 9.2 (voxel slice delay N^2/P entries per pipeline), 1.3 items 4-5 (Cube-4's
#      delay FIFOs); docs/rtl.md (the vg500 top) and docs/cycle.md (the family's rules).

The cycle rung's rule 3 starts a beam when every mini-block beam of its sample window
(voxel rows ``a - 1 .. a + 2`` of voxel slices ``i0 - 1 .. i0 + 2``) is ready, as if the
pipelines read the slab buffer at sample time.  In the published design the voxels stream
through once: each is read one slice ahead of its samples into the slice and beam delay
FIFOs, which give every neighbour.  Here, for the frames the vg500 top renders:

3'. the read stream runs one slice ahead: a priming period reads voxel slice 0, the
    period sampling slice ``j`` reads slice ``j + 1`` (the last reads none); beam ``a`` of
    a period waits only for the mini-block beam holding row ``a`` of the slice it reads,
    usable one clock after its last data beat (the de-skew's write into the slab buffer);
5'. a mini-block beam is freed at the end of the beam reading its last row of its slab's
    later slice;
8'. each ray is pushed into the pixel FIFO when its last sample is written back, the
    latency ``2 C + 56`` after its slot (:func:`stream_latency`: Cube-4's rule 5 with the
    top's units, no crop unit), the bus popping one pixel per clock; the frame ends with
    the last pop.

The SDRAM side is the rung's own (:class:`hwsim.memory.SdramController`, the same burst
order and admission by the buffer's capacity).  Not yet the rung's rule: the transaction
rung shares rule 3's window, and sections, supersampling, skipping and a FIFO that fills
(its freeze) are not modelled here (refused).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.memory import SdramController
from models.machines.common.results import UNITS
from models.machines.volumepro.timing import timing_inputs
from models.units import skew as skew_unit

__all__ = ["DESKEW_WRITE", "FifoTiming", "slice_fifo_timing", "stream_latency"]

#: Clocks from a mini-block beam's last data beat to the slab buffer's read of it: the
#: de-skew network's registered write (architectures.md 9.1: a 1-cycle crossbar [I]).
DESKEW_WRITE = 1


#: The units between the slab buffer and the pixel FIFO in the vg500 top (its pipelines are
#: Cube-4's): no crop unit, which the published VolumePro 500 has (cropping, cut plane [V]).
STREAM_UNITS = ("interp", "gradient", "classify", "shade", "composite")


def stream_latency(beam_cycles: int) -> int:
    """Clocks from a slot's read to the first clock its ray's pixel can leave the pixel
    FIFO when voxels stream through slice and beam delay FIFOs (the structure of Cube-4's
    rule 5, ``models.machines.cube4.timing.cube4_latency``; the machines may not import
    each other): address and de-skew (``skew.LATENCY``), the slice-buffer read 1, beam
    alignment ``C + 1``, gradient look-ahead ``C``, the units' ``LATENCY`` and the FIFO's
    write 1: ``2 C + 56``."""
    C = int(beam_cycles)
    units = sum(UNITS[u].LATENCY for u in STREAM_UNITS)
    return skew_unit.LATENCY + 1 + (C + 1) + C + units + 1


@dataclass
class FifoTiming:
    """A frame under rules 3', 5', 8': its cycles, the clocks the pipelines waited for
    memory, and each beam's first clock (priming period first)."""

    cycles: int
    stall_cycles: int
    beam_begins: np.ndarray


def slice_fifo_timing(machine) -> FifoTiming:
    """Time ``machine``'s frame (a :class:`~models.machines.volumepro.cycle.SlabMachine`,
    built, not run) by the slice-FIFO rules of the module docstring."""
    m = machine
    render = m.plan.scene.render
    if m.skipping or render.supersampling != 1 or m._sections() != [(0, m.n_a)]:
        raise InputError(
            f"{m.arch.name}: the slice-FIFO timing covers one section at supersampling 1 "
            "without skipping",
            key="render.supersampling",
            allowed="1, one section, no early termination or space leaping",
        )
    n_a, n_kp, C = m.n_a, m.n_kp, m.C
    n_u = -(-n_a // 2)
    needed = np.ones((1, -(-n_kp // 2), n_u, -(-m.n_b // 2)), dtype=bool)
    table, _ = timing_inputs(m, [], [(0, n_a)], [0], needed)
    # Beam p n_a + a reads row a of voxel slice p (processing order); p = n_kp reads none.
    slab_of = np.arange(n_kp + 1) // 2
    needs = (slab_of[:, None] * n_u + np.arange(n_a)[None, :] // 2).reshape(-1)
    needs[n_kp * n_a :] = -1
    g = np.arange(len(table))
    last_read = n_a * np.minimum(2 * (g // n_u) + 1, n_kp - 1) + np.minimum(
        2 * (g % n_u) + 1, n_a - 1
    )
    entries = m.capacity["slab_buffer_entries"] + m.faults.slab_buffer_adjust
    capacity = max(entries, 0) // (4 * C)
    begins, stall = _beams(m.memory_cfg, table, needs, last_read, capacity, C)
    return FifoTiming(_last_pop(m, n_kp + 1, stall), stall, begins)


def _beams(memory, table, needs, last_read, capacity, C):
    """Each beam's first clock and the clocks spent waiting (rules 3', 5'), the
    deliveries scheduled in order on one controller per module."""
    dev = memory.sdram
    tail = dev.cas_latency + dev.burst_cycles
    ctls = [SdramController(dev) for _ in range(memory.modules)]
    for k, ctl in enumerate(ctls):
        ctl.reserve(table.bursts(k))
    ready = np.zeros(len(table), dtype=np.int64)
    ends = np.zeros(needs.size, dtype=np.int64)
    begins = np.zeros(needs.size, dtype=np.int64)
    delivered, t, stall = 0, 0, 0
    for beam, need in enumerate(needs.tolist()):
        while need >= delivered:
            earliest = 0
            if delivered >= capacity:
                f = int(last_read[delivered - capacity])
                if f >= beam:
                    raise InputError(
                        f"slab buffer of {capacity} mini-block beams cannot hold the read-ahead",
                        key="buffers.slab_buffer_entries",
                        allowed=f"at least {4 * C * 2} entries",
                    )
                earliest = int(np.ceil(ends[f] * dev.clock_ratio))
            last = 0
            for k, ctl in enumerate(ctls):
                lo, hi = table.starts[k, delivered], table.starts[k, delivered + 1]
                if hi == lo:
                    continue
                arrive = np.zeros(hi - lo, dtype=np.int64)
                arrive[0] = earliest
                ctl._run(table.banks[lo:hi].astype(np.int64), table.rows[lo:hi], arrive)
                last = max(last, int(ctl.reads[-1]) + tail)
            ready[delivered] = int(np.ceil(last / dev.clock_ratio)) + DESKEW_WRITE
            delivered += 1
        begin = t if need < 0 else max(t, int(ready[need]))
        stall += begin - t
        begins[beam], t = begin, begin + C
        ends[beam] = t
    return begins, stall


def _last_pop(m, n_periods: int, stall: int) -> int:
    """Rule 8': per-ray pushes at the slot of the ray's last sample (sampled in the period
    after the one reading its slice), one pop per clock; the clock after the last pop.
    A wait for memory holds the whole top (pipelines, pixel FIFO, bus), so the pushes and
    pops run on the stall-free clock and the frame adds the held clocks."""
    plan, P, C = m.plan, m.P, m.C
    j = plan.j_hi
    pos = plan.position(j, np.arange(plan.ray_ids.size))
    a_ax, b_ax = (ax for ax in range(3) if ax != plan.principal_axis)
    a, b = (
        np.clip(np.floor(p).astype(np.int64) + (p - np.floor(p) >= 0.5), 0, n - 1)
        for p, n in ((pos[:, a_ax], m.n_a), (pos[:, b_ax], m.n_b))
    )  # the voxel a sample is evaluated at (Cube-4's cube4_slots)
    period = m.n_a * C
    push = np.sort((j + 1) * period + a * C + b // P + stream_latency(C) - 1)
    pops = np.empty_like(push)
    pop = -1
    for i, p in enumerate(push.tolist()):  # an entry pushed in a clock leaves the next
        pop = pops[i] = max(pop + 1, p + 1)
    depth = m.capacity["pixel_fifo_entries"]
    if m.faults.pixel_fifo_depth is not None:
        depth = m.faults.pixel_fifo_depth
    waiting = np.arange(1, push.size + 1) - np.searchsorted(pops, push, side="right")
    if push.size and int(waiting.max()) > depth:
        raise InputError(
            f"{m.arch.name}: the pixel FIFO fills (the slice-FIFO timing has no freeze)",
            key="buffers.pixel_fifo_entries",
            allowed=f"at least {int(waiting.max())}",
        )
    end = int(pops[-1]) + 1 if push.size else n_periods * period
    return max(end, n_periods * period) + stall
