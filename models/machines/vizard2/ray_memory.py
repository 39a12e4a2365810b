"""VIZARD II's memory side of the compiled ray loop: block-cache lookups and fills, and
the fills' SDRAM timing (:mod:`models.machines.vizard2.ray_kernel` inlines and calls them).

# Ref: architectures.md section 5 (VoxelCache's 4^3 blocks; SDRAM DIMMs); the rules are the
#      reference's: models/machines/vizard2/memory.py (``BlockCache.fetch``, the memory
#      image) and cycle.py (``VizardMachine._fill``, rule 2).

Lookups run sample by sample in issue order, each sample's distinct blocks in corner order:
what ``BlockCache.fetch`` resolves for a whole step at once (sorted by line, a lookup
missing when its line's previous tag differs).  A sample's up to 8 blocks sit in different
lines (every ``cache_sets`` axis >= 2), so its corners can be read right after its
lookups: the line contents the reference's line-store rows hold for it.
"""

from __future__ import annotations

import numba
import numpy as np

from hwsim.memory.sdram_kernel import schedule_requests
from models.units.interp import cell_weight

__all__ = [
    "FIFO",
    "REGS",
    "fills_timed",
    "gather_round",
    "issue_round",
    "pixel_fifo_advance",
    "retire_packet",
]

#: ``regs`` of the packet kernel, by position.
REGS = (
    "clock",
    "fills",
    "lookups",
    "hits",
    "issued",
    "speculative",
    "samples",
    "cycles",
    "stalls",
    "sdram_requests",
    "fifo_stalls",
    "retired",
)
(_CLOCK, _FILLS, _LOOKUPS, _HITS, _ISSUED, _SPEC, _SAMPLES, _CYCLES, _STALLS, _SD_N,
 _FIFO_STALLS, _RETIRED) = range(12)  # fmt: skip
#: ``fifo`` of :func:`pixel_fifo_advance`, by position (a ``hwsim.engine.DrainFifo``'s state).
FIFO = ("depth", "rate", "occupancy", "max_occupancy", "pushed", "popped", "busy_cycles")


# Divisions by the frame's geometry (cache sets, page columns, banks, rows, pipelines):
# a shift or a mask where the divisor is a power of two, as it mostly is, instead of a
# 64-bit division (tens of clocks) per lookup and per burst.  Non-negative operands only.
@numba.njit(inline="always")
def _log2(d):
    """``log2(d)`` when ``d`` is a power of two, else -1."""
    k = 0
    while (np.int64(1) << k) < d:
        k += 1
    return k if (np.int64(1) << k) == d else -1


@numba.njit(inline="always")
def _div(a, d, shift):
    return a >> shift if shift >= 0 else a // d


@numba.njit(inline="always")
def _mod(a, d, shift):
    return a & (d - 1) if shift >= 0 else a % d


@numba.njit(cache=True, nogil=True)
def _grown(a, need):
    """``a`` (2-D) with at least ``need`` columns (growing fourfold), its columns kept;
    the new ones uninitialised (the scheduler writes every request's column)."""
    if need <= a.shape[1]:
        return a
    b = np.empty((a.shape[0], max(4 * a.shape[1], need)), a.dtype)
    b[:, : a.shape[1]] = a
    return b


@numba.njit(cache=True, nogil=True)
def _grown1(a, need):
    """``a`` (1-D) with at least ``need`` entries (growing fourfold), its entries kept;
    the new ones uninitialised (written before they are read)."""
    if need <= a.shape[0]:
        return a
    b = np.empty(max(4 * a.shape[0], need), a.dtype)
    b[: a.shape[0]] = a
    return b


@numba.njit(inline="always")
def _sort_keys(keys, nk):
    """``keys[0, :nk]`` sorted ascending in place, by insertion: a group's keys come in
    a few ascending runs (each block's bursts are consecutive words), so this is about
    one pass where ``numpy.sort`` called the general quicksort for a few dozen keys."""
    for q in range(1, nk):
        key = keys[0, q]
        p = q - 1
        while p >= 0 and keys[0, p] > key:
            keys[0, p + 1] = keys[0, p]
            p -= 1
        keys[0, p + 1] = key


@numba.njit(cache=True, nogil=True)
def fills_timed(miss_s, miss_b, n_miss, start, stall, P, lay, ratio, sd_out, sd_arr,
                 sd_params, sd_regs, sd_banks, sd_booked, sd_log, regs, keys):  # fmt: skip
    """Rule 2: each lookup group with misses sends its fills' bursts (page by page) to the
    SDRAM when it reaches the cache, and waits for the last beat (``stall[g]``), on the
    controller's state (``sd_*``); returns its four arrays that may grow.  ``keys``:
    scratch, 3 rows of at least ``n_miss`` times a block's bursts (page keys, their
    banks and rows)."""
    vw, gw, gbase, vb, gb, bl, cols, banks, nrows, data_lat, fill_write = lay
    p_sh, c_sh, b_sh, r_sh = _log2(P), _log2(cols), _log2(banks), _log2(nrows)
    waited = 0
    s = 0
    while s < n_miss:
        g = _div(miss_s[s], P, p_sh)
        e = s
        nk = 0
        while e < n_miss and _div(miss_s[e], P, p_sh) == g:
            for k in range(vb + gb):
                if k < vb:
                    addr = miss_b[e] * vw + k * bl
                else:
                    addr = gbase + miss_b[e] * gw + (k - vb) * bl
                page = _div(addr, cols, c_sh)
                keys[0, nk] = _mod(page, banks, b_sh) * nrows + _div(page, banks, b_sh)
                nk += 1
            e += 1
        arrive = start + g + waited
        _sort_keys(keys, nk)  # lexsort((rows, banks)): bank, then row
        for q in range(nk):
            keys[1, q] = _div(keys[0, q], nrows, r_sh)
            keys[2, q] = _mod(keys[0, q], nrows, r_sh)
        earliest = np.int64(np.ceil(arrive * ratio))
        first = regs[_SD_N]
        need = first + nk
        if need > sd_out.shape[1] or need > sd_arr.shape[0]:  # a call only to grow
            sd_out, sd_arr = _grown(sd_out, need), _grown1(sd_arr, need)
        for q in range(first, need):
            sd_arr[q] = earliest
        sd_booked, sd_log = schedule_requests(
            sd_params, sd_regs, sd_banks, keys[1, :nk], keys[2, :nk], sd_arr[first:need],
            sd_out, first, sd_booked, sd_log,
        )  # fmt: skip
        regs[_SD_N] = need
        last = sd_out[0, first]
        for q in range(first + 1, need):
            last = max(last, sd_out[0, q])
        last += data_lat
        ready = np.int64(np.ceil(last / ratio)) + fill_write
        if ready > arrive:
            stall[g] += ready - arrive
            waited += ready - arrive
        s = e
    return sd_out, sd_arr, sd_booked, sd_log


@numba.njit(cache=True, nogil=True)
def gather_round(n, live, ray_ids, orig, dirs, t, shape, nb, sets, tag, cvals, cgx, cgy, cgz,
                 ivals, igx, igy, igz, grads, values, keep_dead, faults, miss_s, miss_b, regs,
                 alive, before, weights, corners, w_bits, w_code):  # fmt: skip
    """A round's ``n`` samples (plan rays ``live``, at ray parameter ``t``) in issue order:
    each one's position, cell and quantised weights (``SamplePlan.position``'s expression,
    :func:`~models.units.interp.cell_weight`; ``weights[i]``), the cache lookups of its
    cell's distinct blocks in corner order (a miss fills its direct-mapped line: its
    words copied only when ``values``; the miss noted in ``miss_s``/``miss_b``), its
    ray's state before the round (``before[i]``) and, when ``values`` and the ray is
    live (or ``keep_dead``), its corners as the lines hold them right after its lookups
    (``corners[i]``: 8 values, then 8 each of the gradient table's x, y, z when
    ``grads``).  One call per round: no array is handed to a per-sample helper (each
    would cost a reference count per sample).  Returns the round's miss count."""
    n_miss = 0
    per_ray_dir = dirs.shape[0] > 1
    s0, s1, s2 = sets[0], sets[1], sets[2]
    h0, h1, h2 = _log2(s0), _log2(s1), _log2(s2)
    # The line stores flat (views): a corner's word is one index (lines of 64 words).
    flat_v, flat_x = cvals.reshape(-1), cgx.reshape(-1)
    flat_y, flat_z = cgy.reshape(-1), cgz.reshape(-1)
    for i in range(n):
        r = live[i]
        dr = r if per_ray_dir else 0
        # Position, cell and weights (``interp.interp_taps``), one axis at a time.
        p0, q0 = cell_weight(orig[r, 0] + t * dirs[dr, 0], shape[0] - 1.0, w_bits, w_code)
        p1, q1 = cell_weight(orig[r, 1] + t * dirs[dr, 1], shape[1] - 1.0, w_bits, w_code)
        p2, q2 = cell_weight(orig[r, 2] + t * dirs[dr, 2], shape[2] - 1.0, w_bits, w_code)
        z0, y0, x0 = np.int64(p0), np.int64(p1), np.int64(p2)
        z1 = z0 + (1 if shape[0] > 1 else 0)
        y1 = y0 + (1 if shape[1] > 1 else 0)
        x1 = x0 + (1 if shape[2] > 1 else 0)
        weights[i, 0], weights[i, 1], weights[i, 2] = np.int64(q0), np.int64(q1), np.int64(q2)
        # Each axis's two block coordinates and their sets; the distinct blocks in corner
        # order (a corner's block is a lower corner's unless all its set axes cross).
        bz0, by0, bx0 = z0 >> 2, y0 >> 2, x0 >> 2
        bz1, by1, bx1 = z1 >> 2, y1 >> 2, x1 >> 2
        sz0, sy0, sx0 = _mod(bz0, s0, h0), _mod(by0, s1, h1), _mod(bx0, s2, h2)
        sz1, sy1, sx1 = _mod(bz1, s0, h0), _mod(by1, s1, h1), _mod(bx1, s2, h2)
        for dz in range(2 if bz1 != bz0 else 1):
            bz, sz = (bz1, sz1) if dz else (bz0, sz0)
            for dy in range(2 if by1 != by0 else 1):
                by, sy = (by1, sy1) if dy else (by0, sy0)
                for dx in range(2 if bx1 != bx0 else 1):
                    bx, sx = (bx1, sx1) if dx else (bx0, sx0)
                    at = (sz * s1 + sy) * s2 + sx
                    block = (bz * nb[1] + by) * nb[2] + bx
                    regs[_LOOKUPS] += 1
                    if tag[at] == block:
                        regs[_HITS] += 1
                        continue
                    tag[at] = block
                    # The fill: the line gets the block from the memory image, the value
                    # XORed on the corrupted line, nothing on the dropped fill (written
                    # here: a helper handed these arrays costs a reference count a fill).
                    if values and regs[_FILLS] != faults[2]:
                        xor = faults[1] if at == faults[0] else 0
                        for o in range(64):
                            cvals[at, o] = ivals[block, o] ^ xor
                        for o in range(64 if grads else 0):
                            cgx[at, o] = igx[block, o]
                            cgy[at, o] = igy[block, o]
                            cgz[at, o] = igz[block, o]
                    regs[_FILLS] += 1
                    miss_s[n_miss], miss_b[n_miss] = i, block
                    n_miss += 1
        live_ray = alive[ray_ids[r]]
        before[i] = live_ray
        if not values or not (live_ray or keep_dead):
            continue
        # Where the datapath reads each corner: line ``(sz s1 + sy) s2 + sx``, word
        # ``(z & 3) 16 + (y & 3) 4 + (x & 3)``, as one flat index summed per axis.
        az0, az1 = (sz0 * s1 * s2 << 6) + ((z0 & 3) << 4), (sz1 * s1 * s2 << 6) + ((z1 & 3) << 4)
        ay0, ay1 = (sy0 * s2 << 6) + ((y0 & 3) << 2), (sy1 * s2 << 6) + ((y1 & 3) << 2)
        ax0, ax1 = (sx0 << 6) + (x0 & 3), (sx1 << 6) + (x1 & 3)
        at8 = (az0 + ay0 + ax0, az0 + ay0 + ax1, az0 + ay1 + ax0, az0 + ay1 + ax1,
               az1 + ay0 + ax0, az1 + ay0 + ax1, az1 + ay1 + ax0, az1 + ay1 + ax1)  # fmt: skip
        for c in range(8):
            corners[i, c] = flat_v[at8[c]]
        if grads:
            for c in range(8):
                corners[i, 8 + c] = flat_x[at8[c]]
                corners[i, 16 + c] = flat_y[at8[c]]
                corners[i, 24 + c] = flat_z[at8[c]]
    return n_miss


@numba.njit(inline="always")
def issue_round(n, P, stall, clock, busy, ert_on, before, alive, ray_ids, live, terminated_at,
                issue, regs):  # fmt: skip
    """Rules 1 and 3 for a round of ``n`` samples from ``clock``: each sample's issue cycle
    (its group's, after the stalls so far), the lanes' busy counts, speculative samples
    and the issue cycle of each ray's terminating sample; the clock moves to the end."""
    waited = 0
    group = lane = 0  # i // P and i % P, counted
    for i in range(n):
        if lane == 0:
            waited += stall[group]
        issue[i] = clock + group + waited
        busy[lane] += 1
        lane += 1
        if lane == P:
            lane = 0
            group += 1
        if ert_on:
            if not before[i]:
                regs[_SPEC] += 1
            elif not alive[ray_ids[live[i]]]:
                terminated_at[live[i]] = issue[i]
    end = clock + (n + P - 1) // P + waited
    regs[_CLOCK] = end
    regs[_CYCLES] += end - clock
    regs[_STALLS] += waited
    regs[_ISSUED] += n


@numba.njit(inline="always")
def _fifo_drain(fifo, cycles):
    out = min(fifo[2], cycles * fifo[1])
    fifo[6] += -(-out // fifo[1])
    fifo[2] -= out
    fifo[5] += out


@numba.njit(cache=True, nogil=True)
def pixel_fifo_advance(fifo, cycles, arrivals):
    """``hwsim.engine.DrainFifo.advance`` on its state ``fifo`` (:data:`FIFO`; depth > 0,
    the caller's check: a FIFO of depth 0 is a deadlock the Python FIFO reports): drain
    for ``cycles`` cycles, push ``arrivals`` entries; returns the producer's stall cycles."""
    depth, rate = fifo[0], fifo[1]
    _fifo_drain(fifo, cycles)
    stall = 0
    space = depth - fifo[2]
    remaining = arrivals
    while remaining > space:
        fifo[2] += space
        remaining -= space
        fifo[3] = max(fifo[3], fifo[2])
        need = -(-remaining // rate) if remaining <= depth else -(-depth // rate)
        _fifo_drain(fifo, need)
        stall += need
        space = depth - fifo[2]
    fifo[2] += remaining
    fifo[4] += arrivals
    fifo[3] = max(fifo[3], fifo[2])
    return stall


@numba.njit(cache=True, nogil=True)
def retire_packet(packet, ray_ids, acc, touched, bus_acc, bus_touched, fifo, regs):
    """Rule 5: a retiring packet's accumulators cross to the pixel bus (``bus_*``) and its
    pixels enter the pixel FIFO (:func:`pixel_fifo_advance`, drained since the last
    retirement); a full FIFO stalls the issue (the clock moves on)."""
    for q in range(packet.shape[0]):
        ray = ray_ids[packet[q]]
        for c in range(acc.shape[1]):
            bus_acc[ray, c] = acc[ray, c]
        bus_touched[ray] = touched[ray]
    stall = pixel_fifo_advance(fifo, regs[_CLOCK] - regs[_RETIRED], packet.shape[0])
    regs[_CLOCK] += stall
    regs[_FIFO_STALLS] += stall
    regs[_RETIRED] = regs[_CLOCK]
