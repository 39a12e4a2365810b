"""VIZARD II's timing-only model: packets, rounds and page runs, compiled (issue 36).

# Ref: docs/cycle.md "VIZARD II" timing rules 1-6; architectures.md section 5 (ray
#      queueing, VoxelCache's 4^3 blocks, early ray termination, space leaping);
#      docs/memory.md "Timing rules" (the SDRAM's published command timings).

The transaction rung's default timing of a VIZARD II frame, written from the machine's
rules and not from the cycle rung's code (:mod:`models.machines.vizard2.ray_kernel`,
:mod:`~models.machines.vizard2.ray_memory`, ``hwsim.memory.SdramController``):

* **packets and rounds** (rules 1, 5): the ray generator's packets (``ray_queue_entries``
  rays of one ``ray_tile``); round ``j`` issues the packet's live rays' step ``j``, ``P``
  per clock, so ``ceil(live / P)`` clocks plus the stalls of its missing lookup groups;
* **the block cache** as tags only: a sample looks up the distinct 4^3 blocks of its
  trilinear cell (the cell from the clamped, floored position of the plan's ray: the
  interpolator's rule), each against its direct-mapped line (``cache_sets``); a miss
  takes the line.  No voxel is read;
* **fills** (rule 2): a lookup group's misses are its fills' bursts (the arch file's
  words per block and per gradient-table entry, burst length, page size and banks),
  gathered into **page runs** (same bank and row, sorted by bank then row) and timed a
  run at a time from the published SDRAM timings, not burst by burst: the run's first
  READ after its row opens (hit: ``t_rcd`` after its ACTIVATE; miss: ``t_rp``, ``t_rc``,
  ``t_rrd``; conflict: PRECHARGE after ``t_ras`` and the bank's last burst), its other
  bursts ``burst_cycles`` apart on the data bus, admission ``queue_depth - 1`` READs
  back; refresh every ``t_refi`` (PRECHARGE-ALL, ``t_rp``, ``t_rfc``, every bank closed
  after it) between runs, splitting a run where one falls due inside it; the issue
  waits for the last beat (``cas_latency + burst_cycles`` after its READ) plus the line
  write (``FILL_WRITE``).  The one-command-per-clock command bus is not modelled;
* **early ray termination** (rule 3): each ray's terminating step from the functional
  rung (``ReadsTheFrame.termination_steps``); the ray stops issuing from the first round
  that starts ``FEEDBACK`` clocks after that step's sample issued, in this model's clocks;
* **space leaping** (rule 4): the leaped plan (the host geometry both rungs compute with
  ``Backend.occupied_blocks`` and ``SamplePlan.leap``);
* **pixel FIFO** (rules 5, 6): one pixel a clock drains; a packet that does not fit
  stalls the issue by what it overflows; ``FEEDBACK`` and the final drain added once.

Nothing is fitted: every term is a rule above or a value of the arch file.  What this
shares with the cycle rung: the arch file's values, the constants ``FEEDBACK`` and
``FILL_WRITE``, the plan (positions, leap ranges), the packet order
(``VizardTransaction._packets``) and the memory layout's sizes (``BlockLayout``'s fields).
"""

from __future__ import annotations

import numba
import numpy as np

from models.machines.common.transaction import report_progress
from models.machines.vizard2.config import FEEDBACK, FILL_WRITE

__all__ = ["COUNTERS", "PacketTiming"]

#: The kernel's counters, by position.
COUNTERS = (
    "frame.pipe_cycles",
    "cache.lookups",
    "cache.fills",
    "cache.miss_groups",
    "memory.bursts",
    "memory.row_hits",
    "memory.row_misses",
    "memory.row_conflicts",
    "memory.refreshes",
    "memory.stall_cycles",
    "frame.issued_samples",
    "ert.speculative_samples",
    "pixel_bus.busy_cycles",
    "pixel_bus.max_occupancy",
    "pixel_bus.drain_cycles",
    "pixel_bus.stall_cycles",
)
(_CLOCK, _LOOKUPS, _FILLS, _GROUPS, _BURSTS, _HIT, _MISS, _CONFLICT, _REFRESH, _STALL,
 _ISSUED, _SPEC, _PX_BUSY, _PX_MAX, _PX_DRAIN, _PX_STALL) = range(len(COUNTERS))  # fmt: skip

# Parameters (``pa``): the memory layout's, then the SDRAM's published timings.
(_VW, _GW, _GBASE, _VB, _GB, _BL, _COLS, _BANKS, _ROWS, _CL, _BC, _RCD, _RP, _RAS, _RC,
 _RRD, _REFI, _RFC, _QD, _OPEN, _P, _FIFO, _S1, _S2, _LINES, _LOG_COLS, _LOG_BL, _LOG_BANKS,
 _LOG_ROWS) = range(29)  # fmt: skip
# State (``st``) after the counters: next refresh due, last ACTIVATE, data bus free,
# admission floor, READs issued; then per bank its open row, ACTIVATE and free cycle,
# then the last ``queue_depth`` READs.  One array: each array a helper takes costs
# reference counts per call.
_DUE, _LAST_ACT, _BUS, _ADMIT, _READS, _OCC, _RETIRED = range(len(COUNTERS), len(COUNTERS) + 7)
_BANK0 = len(COUNTERS) + 7


@numba.njit(inline="always")
def _refresh(a, pa, st):
    """Refreshes due by admission ``a``: each at its due cycle or after the bursts in
    flight, PRECHARGE-ALL after ``t_ras``, ``t_rp``, then ``t_rfc``; every bank closed.
    Returns the admission after them."""
    nb = pa[_BANKS]
    while pa[_REFI] > 0 and st[_DUE] <= a:
        pre = max(st[_DUE], st[_BUS])
        for b in range(nb):
            if st[_BANK0 + b] >= 0:
                pre = max(pre, st[_BANK0 + nb + b] + pa[_RAS])
            st[_BANK0 + b] = -1
        done = pre + pa[_RP] + pa[_RFC]
        a = max(a, done)
        st[_BUS] = max(st[_BUS], done)
        st[_DUE] += pa[_REFI]
        st[_REFRESH] += 1
    return a


@numba.njit(inline="always")
def _page_run(bank, row, k, arrive, pa, st):
    """``k`` bursts of one page (bank, row) from ``arrive``; returns the last READ."""
    nb, bc, qd, is_open = pa[_BANKS], pa[_BC], pa[_QD], pa[_OPEN] != 0
    o_row, o_act, o_free = _BANK0 + bank, _BANK0 + nb + bank, _BANK0 + 2 * nb + bank
    o_ring = _BANK0 + 3 * nb
    last = arrive
    while k > 0:
        a = _refresh(max(arrive, st[_ADMIT]), pa, st)
        if is_open and st[o_row] == row:  # row hit
            rd = max(a, st[o_act] + pa[_RCD], st[_BUS])
        else:
            if st[o_row] >= 0:  # conflict: PRECHARGE first
                ready = max(a, st[o_act] + pa[_RAS], st[o_free]) + pa[_RP]
                st[_CONFLICT] += 1
            else:
                ready = max(a, st[o_free])
                st[_MISS] += 1
            t_act = max(ready, st[o_act] + pa[_RC], st[_LAST_ACT] + pa[_RRD])
            st[o_act], st[_LAST_ACT], st[o_row] = t_act, t_act, row
            rd = max(t_act + pa[_RCD], st[_BUS])
            st[_HIT] -= 1  # the run's first burst is counted above
        # The run's bursts up to one admitted (the READ queue_depth - 1 back) at or after
        # a refresh's due cycle; closed page: one burst per ACTIVATE.
        take = k if is_open else 1
        if pa[_REFI] > 0 and take > qd - 1:
            # READ m is admitted at the READ ``qd - 1`` back, ``u = m - qd + 1`` bursts
            # after the first: the first at or after the due cycle has the least ``u``
            # with ``rd + u bc >= due`` (found by division, not a loop over the run).
            late = st[_DUE] - rd
            u = 0 if late <= 0 else (-(-late // bc) if bc > 0 else take)
            if u + qd - 1 < take:
                take = max(u + qd - 1, 1)
        last = rd + (take - 1) * bc
        st[_HIT] += take
        st[_BUS] = last + bc
        if is_open:
            st[o_free] = last + bc
        else:  # auto-precharge after the burst and t_ras, t_rp before the next ACTIVATE
            st[o_free] = max(last + bc, st[o_act] + pa[_RAS]) + pa[_RP]
            st[o_row] = -1
        # Admission floor of the next request: the READ queue_depth - 1 requests back.
        if take >= qd - 1:
            st[_ADMIT] = max(st[_ADMIT], rd + (take - qd + 1) * bc)
        else:  # deeper queues: from the last READs kept
            for m in range(take):
                st[o_ring + (st[_READS] + m) % qd] = rd + m * bc
            if st[_READS] + take >= qd - 1:
                back = st[o_ring + (st[_READS] + take - (qd - 1)) % qd]
                st[_ADMIT] = max(st[_ADMIT], back)
        st[_READS] += take
        k -= take
    return last


@numba.njit(inline="always")
def _div(a, d, log):
    """``a // d`` for ``a >= 0``: a shift when ``d`` is ``2**log`` (``log >= 0``)."""
    return a >> log if log >= 0 else a // d


@numba.njit(inline="always")
def _runs_of(base, bursts, pa, banks_of, rows_of, counts, nk):
    """The page runs of ``bursts`` bursts from word ``base`` appended as (bank, row,
    bursts) from ``nk``; returns the new count."""
    bl, cols, banks = pa[_BL], pa[_COLS], pa[_BANKS]
    while bursts > 0:
        page = _div(base, cols, pa[_LOG_COLS])
        fit = min(bursts, _div((page + 1) * cols - base + bl - 1, bl, pa[_LOG_BL]))
        row = _div(page, banks, pa[_LOG_BANKS])
        banks_of[nk], rows_of[nk], counts[nk] = page - row * banks, row, fit
        nk += 1
        bursts -= fit
        base += fit * bl
    return nk


@numba.njit(inline="always")  # inlined: a call took reference counts on six arrays
def _fill(blocks, n, arrive, pa, st, banks_of, rows_of, counts):
    """Rule 2 for one lookup group's ``n`` fills (``blocks``): their bursts as page runs,
    sorted (bank, then row) and timed a run at a time; returns the cycle the issue
    resumes (last beat, then the line write)."""
    nk = 0
    for e in range(n):
        nk = _runs_of(blocks[e] * pa[_VW], pa[_VB], pa, banks_of, rows_of, counts, nk)
        if pa[_GB]:
            base = pa[_GBASE] + blocks[e] * pa[_GW]
            nk = _runs_of(base, pa[_GB], pa, banks_of, rows_of, counts, nk)
    st[_BURSTS] += n * (pa[_VB] + pa[_GB])
    for q in range(1, nk):  # insertion sort: a group holds a few page runs
        b, r, c, at = banks_of[q], rows_of[q], counts[q], q
        while at > 0 and (banks_of[at - 1] > b or (banks_of[at - 1] == b and rows_of[at - 1] > r)):
            banks_of[at], rows_of[at], counts[at] = (
                banks_of[at - 1],
                rows_of[at - 1],
                counts[at - 1],
            )
            at -= 1
        banks_of[at], rows_of[at], counts[at] = b, r, c
    last, s = arrive, 0
    while s < nk:
        k, e = counts[s], s + 1
        while e < nk and banks_of[e] == banks_of[s] and rows_of[e] == rows_of[s]:
            k += counts[e]
            e += 1
        last = _page_run(banks_of[s], rows_of[s], k, arrive, pa, st)
        s = e
    st[_GROUPS] += 1
    return last + pa[_CL] + pa[_BC] + FILL_WRITE


@numba.njit(inline="always")
def _cell_blocks(p, hi):
    """Blocks of the low and high voxel of the trilinear cell holding index position
    ``p`` on an axis of ``hi + 1`` voxels (clamped, floored; one voxel: the same)."""
    z = np.int64(min(np.floor(min(max(p, 0.0), hi)), max(hi - 1.0, 0.0)))
    return z >> 2, (z + (1 if hi > 0 else 0)) >> 2


@numba.njit(inline="always")
def _keys(set_of, nb, pa):
    """Per axis and block, its term of the block index shifted past the line plus its term
    of the line: a lookup's block and line are one sum of three, exact (the line is below
    ``2**shift``, the block below ``2**(63 - shift)``).  Returns the three and ``shift``."""
    s1, s2, shift = pa[_S1], pa[_S2], 1
    while (np.int64(1) << shift) < pa[_LINES]:
        shift += 1
    n = set_of.shape[1]
    key_z, key_y, key_x = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.int64)
    for b in range(n):
        key_z[b] = ((b * nb[1] * nb[2]) << shift) + set_of[0, b] * s1 * s2
        key_y[b] = ((b * nb[2]) << shift) + set_of[1, b] * s2
        key_x[b] = (b << shift) + set_of[2, b]
    return key_z, key_y, key_x, shift


# error_model="numpy": no zero test before each integer division (none of its divisors
# can be 0: pipelines, page and burst sizes, banks, rows >= 1, queue depth >= 2).
@numba.njit(cache=True, nogil=True, error_model="numpy")
def _packets(order, cuts, first, end, j_lo, j_hi, ray_ids, orig, dirs, dts, k_first, k_dir, hi,
             nb, set_of, pa, st, tag, term, stopped, ert_on):  # fmt: skip
    """Rules 1-5 for packets ``first`` to ``end``: each packet's rounds, each round's
    samples in issue order (lookups of their cells' distinct blocks, each missing group's
    fills), then the packet's pixels into the FIFO; counters and state in ``st``, the
    cache's tags in ``tag``, the rays' terminating issue clocks in ``term``."""
    P, h0, h1, h2 = pa[_P], hi[0], hi[1], hi[2]
    runs = 8 * P * 2 * (pa[_VB] + pa[_GB])  # at most two page runs a fill's region
    miss, counts = np.empty(8 * P, np.int64), np.empty(runs, np.int64)
    banks_of, rows_of = np.empty(runs, np.int64), np.empty(runs, np.int64)
    ending, live = np.empty(P, np.int64), np.empty(max(np.diff(cuts).max(), 1), np.int64)
    per_dir, per_dt = dirs.shape[0] > 1, dts.shape[0] > 1
    cells = np.empty((6, live.size), np.int64)  # the round's blocks: low, high by axis
    occupancy, retired = st[_OCC], st[_RETIRED]
    key_z, key_y, key_x, shift = _keys(set_of, nb, pa)  # a lookup's block and line
    mask = (np.int64(1) << shift) - 1
    for p in range(first, end):
        packet = order[cuts[p] : cuts[p + 1]]
        for j in range(j_lo[packet].min(), j_hi[packet].max() + 1):
            clock, n = st[_CLOCK], 0
            for r in packet:
                if j_lo[r] <= j <= j_hi[r] and not (ert_on and clock >= term[r] + FEEDBACK):
                    live[n] = r
                    n += 1
            waited = n_miss = n_end = lane = g = lookups = fills = 0
            t_round = (k_first + k_dir * j) * dts[0]
            for i in range(n):  # the round's cells first: a short loop of arithmetic only
                r = live[i]
                t = (k_first + k_dir * j) * dts[r] if per_dt else t_round
                d = r if per_dir else 0
                cells[0, i], cells[1, i] = _cell_blocks(orig[r, 0] + t * dirs[d, 0], h0)
                cells[2, i], cells[3, i] = _cell_blocks(orig[r, 1] + t * dirs[d, 1], h1)
                cells[4, i], cells[5, i] = _cell_blocks(orig[r, 2] + t * dirs[d, 2], h2)
            for i in range(n + 1 if n else 0):
                if i == n or lane == P:  # lookup group g complete
                    if n_miss:
                        arrive = clock + g + waited
                        ready = _fill(miss, n_miss, arrive, pa, st, banks_of, rows_of, counts)
                        waited += max(ready - arrive, 0)
                    for e in range(n_end):  # rule 3: the terminating samples' issue clock
                        term[ending[e]] = clock + g + waited
                    n_miss = n_end = lane = 0
                    g += 1
                    if i == n:
                        break
                lane += 1
                r = live[i]
                z0, z1, y0, y1 = cells[0, i], cells[1, i], cells[2, i], cells[3, i]
                x0, x1 = cells[4, i], cells[5, i]
                # Unsigned indices (all >= 0): no negative-index wrap on each read.
                for bz in range(z0, z1 + 1):
                    for by in range(y0, y1 + 1):
                        key_zy = key_z[np.uint64(bz)] + key_y[np.uint64(by)]
                        for bx in range(x0, x1 + 1):
                            key = key_zy + key_x[np.uint64(bx)]
                            line, block = np.uint64(key & mask), key >> shift
                            lookups += 1
                            if tag[line] != block:
                                tag[line], miss[np.uint64(n_miss)] = block, block
                                n_miss += 1
                                fills += 1
                if ert_on:
                    stop = stopped[ray_ids[r]]
                    if stop == j:
                        ending[n_end] = r
                        n_end += 1
                    elif stop < j:
                        st[_SPEC] += 1
            st[_CLOCK] = clock + (n + P - 1) // P + waited
            st[_ISSUED] += n
            st[_STALL] += waited
            st[_LOOKUPS] += lookups
            st[_FILLS] += fills
        # Rule 5: the packet's pixels into the FIFO, one leaving a clock.
        out = min(occupancy, st[_CLOCK] - retired)
        over = occupancy - out + packet.shape[0] - pa[_FIFO]
        st[_PX_BUSY] += out + max(over, 0)
        st[_PX_STALL] += max(over, 0)
        st[_CLOCK] += max(over, 0)
        occupancy = min(occupancy - out + packet.shape[0], pa[_FIFO])
        st[_PX_MAX] = max(st[_PX_MAX], occupancy)
        retired = st[_CLOCK]
    st[_OCC], st[_RETIRED] = occupancy, retired


def _log2(value: int) -> int:
    """``log2(value)`` for a power of two, else -1 (the kernel then divides)."""
    return value.bit_length() - 1 if value > 0 and value & (value - 1) == 0 else -1


class PacketTiming:
    """The compiled packet model of one :class:`VizardTransaction`'s frame (its plan,
    packets, buffers, memory and termination steps)."""

    def __init__(self, txn) -> None:
        self.txn = txn

    def refusal(self) -> str | None:
        """Why this model does not time the frame (the rung then takes the cycle rung's
        loop or the SimPy model), or None."""
        txn, plan = self.txn, self.txn.plan
        sd = txn.memory.sdram
        if plan.kind != "ray" or np.ndim(plan.k_first) or np.ndim(plan.k_dir):
            return "not a ray plan with one step rule"
        if sd.queue_depth < 2:
            return "memory.queue_depth 1 (the admission rule reads the READ queue_depth - 1 back)"
        if txn.pixel_fifo_depth <= 0 or txn.buffers.ray_queue_entries <= 0:
            return "a buffer of depth 0 (the cycle rung reports the deadlock)"
        return None

    def run(self) -> tuple[int, dict]:
        """The frame's cycles and counters."""
        txn, plan = self.txn, self.txn.plan
        lay, sd = txn.layout, txn.memory.sdram
        order, cuts = txn._packet_order()
        packets = range(cuts.size - 1)
        geo = (
            plan.ray_ids.astype(np.int64),
            np.ascontiguousarray(plan._o, dtype=np.float64),
            np.ascontiguousarray(plan._d, dtype=np.float64).reshape(-1, 3),
            np.atleast_1d(np.asarray(plan._dt, dtype=np.float64)),
            float(plan.k_first),
            float(plan.k_dir),
        )
        sets = np.asarray(txn.buffers.cache_sets, np.int64)
        pa = np.array(
            [lay.value_words, lay.gradient_words, lay.gradient_base, lay.value_bursts,
             lay.gradient_bursts, lay.burst_length, lay.columns, lay.banks, sd.rows,
             sd.cas_latency, sd.burst_cycles, sd.t_rcd, sd.t_rp, sd.t_ras, sd.t_rc, sd.t_rrd,
             sd.t_refi, sd.t_rfc, sd.queue_depth, sd.page_policy == "open", txn.P,
             txn.pixel_fifo_depth, sets[1], sets[2], txn.buffers.cache_lines,
             *(_log2(v) for v in (lay.columns, lay.burst_length, lay.banks, sd.rows))],
            dtype=np.int64,
        )  # fmt: skip
        # Counters, then: next refresh due (refresh k at k t_refi), last ACTIVATE, bus
        # free, admission floor, READs; per bank open row (none), ACTIVATE, free; READs.
        big = np.int64(1) << 60
        st = np.concatenate(
            [np.zeros(len(COUNTERS)), [sd.t_refi, -big, 0, 0, 0, 0, 0], np.full(lay.banks, -1),
             np.full(lay.banks, -big), np.zeros(lay.banks + sd.queue_depth)]
        ).astype(np.int64)  # fmt: skip
        stopped = txn.termination_steps(txn.frame) if txn.ert else None
        never = np.full(int(plan.ray_ids.max(initial=0)) + 1, big)
        stopped = never if stopped is None else np.asarray(stopped, dtype=np.int64)
        set_of = np.arange(max(lay.nb) + 1)[None, :] % sets[:, None]  # block -> set, by axis
        tag = np.full(txn.buffers.cache_lines, -1, np.int64)
        term = np.full(plan.ray_ids.size, big, np.int64)
        j_lo, j_hi = plan.j_lo.astype(np.int64), plan.j_hi.astype(np.int64)
        hi = np.asarray(txn.volume.shape, np.float64) - 1.0
        # Sixteen calls where someone follows the progress (each call costs ~40 us of
        # argument passing), one where nobody does (sweeps, benchmarks, tests).
        chunks = 16 if getattr(txn, "progress", None) is not None else 1
        steps = np.linspace(0, len(packets), min(len(packets), chunks) + 1).astype(int)
        for first, end in zip(steps[:-1].tolist(), steps[1:].tolist(), strict=True):
            _packets(
                order, cuts, first, end, j_lo, j_hi, *geo, hi, np.asarray(lay.nb, np.int64),
                set_of, pa, st, tag, term, stopped, txn.ert,
            )  # fmt: skip
            report_progress(txn, end, len(packets))
        st[_PX_DRAIN] = st[_OCC]  # rule 6: the FIFO drains at the end
        st[_PX_BUSY] += st[_OCC]
        regs = st[: len(COUNTERS)]
        counters = {k: int(v) for k, v in zip(COUNTERS, regs, strict=True)}
        cycles = counters["frame.pipe_cycles"] + FEEDBACK + counters["pixel_bus.drain_cycles"]
        counters.update(
            {
                "cache.lines": txn.buffers.cache_lines,
                "cache.hits": counters["cache.lookups"] - counters["cache.fills"],
                "cache.misses": counters["cache.fills"],
                # One ACTIVATE opens the row of each row miss and each row conflict
                # (docs/memory.md; the energy model prices them per command).
                "memory.activates": counters["memory.row_misses"]
                + counters["memory.row_conflicts"],
                "ray_generator.rays": int(plan.ray_ids.size),
                "pixel_bus.pixels": int(plan.ray_ids.size),
                "pipeline.latency_cycles": FEEDBACK,
                "frame.cycles": cycles,
                "frame.planned_samples": txn.planned.samples,
                "frame.leaped_samples": txn.planned.samples - plan.samples,
                "transaction.fill_write_cycles": FILL_WRITE,
            }
        )
        return cycles, counters
