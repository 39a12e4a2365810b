"""VIZARD II as a SimPy event model at ray-packet granularity (the ``transaction`` rung).

:meth:`VizardTransaction.run` times a frame on the compiled packet model
(:mod:`models.machines.vizard2.packet_timing`, the default), else on the cycle rung's
ray loop (``shared_loop``, and where the packet model refuses the frame), else here
(:meth:`VizardTransaction.play`, also on request: ``event_model``).

# Ref: docs/cycle.md "VIZARD II" timing rules 1-6 (the rules this model approximates);
#      architectures.md section 5 (image-order ray casting, ray queueing, VoxelCache's
#      4^3 blocks, pre-computed gradient table, early ray termination, space leaping).

The frame is a sequence of *packets* (a tile's rays, ``ray_queue_entries`` at a time, in
the ray generator's order).  For each packet, at once and without any voxel:

* its samples in issue order (round after round, the packet's live rays in order), from
  the plan's positions; which rays are live comes from the rays' sample ranges (the
  leaped plan when the machine leaps) and, with early-termination hardware, from each
  ray's termination step as the **functional rung** reports it
  (:attr:`models.functional.FunctionalResult.stopped`);
* the block lookups (the up to 8 blocks of a sample's cell, distinct ones only) resolved
  against a *tag-only* model of the direct-mapped block cache in one vectorised pass;
* its **miss groups**: the lookup groups (``P`` samples of one clock) holding a miss,
  each with the SDRAM bursts of its fills (value region, and the gradient table when the
  scene needs gradients).

A SimPy process then plays the packets: issue clocks as timeouts, each miss group's
bursts as one read on the shared :class:`hwsim.memory.SdramTransactionPort` (sorted
page by page, as the machine's fill sequencer does) that blocks the issue until its last
beat plus the line write; a retiring packet pushes its pixels into the pixel FIFO
(:class:`models.machines.common.pixel_bus.PixelBus`).

What is coarser than the cycle rung (the error's sources): **early termination** is
decided per packet from stall-free round lengths (a ray keeps issuing until a round
starts ``FEEDBACK`` clocks after its terminating sample; the cycle rung measures that
with the real, stalled clocks, so this model issues a few more speculative samples), and
the speculative samples' lookups follow from that estimate.  Without a termination
threshold the cache, bursts and clocks are resolved exactly as the machine's rules say.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import time
import weakref
from typing import Any

import numba
import numpy as np
import simpy

from hwsim.golden.occupancy import Occupancy, occupancy_from_ranges
from hwsim.golden.positions import SamplePlan
from hwsim.memory import SdramTransactionPort
from hwsim.spec.transfer import TransferFunction
from models.backend import Backend
from models.datapath import units_needed
from models.frame import Frame
from models.machines.common.pixel_bus import PixelBus
from models.machines.common.transaction import (
    ReadsTheFrame,
    TxnTiming,
    report_progress,
    require_pipeline_clock,
)
from models.machines.vizard2.config import (
    BLOCK,
    FEEDBACK,
    FILL_WRITE,
    VizardFaults,
    check_frame,
    memory_of,
    parse_buffers,
)
from models.machines.vizard2.memory import BlockLayout
from models.machines.vizard2.packet_timing import PacketTiming
from models.units import interp as interp_unit

__all__ = ["VizardTransaction"]

#: Distance fields of the last few occupancies, by their blocks' bits: an occupancy is the
#: volume's and the transfer function's (never the view's), so the frames of a turntable
#: or a sweep leap through one field without a distance transform each.
_DISTANCES: dict[tuple, Occupancy] = {}
_DISTANCES_KEPT = 4


#: Per volume (weakly, as :data:`models.backend._RANGES`): the leap's occupancy by what
#: else decides the occupied blocks, the datapath, the render mode and iso value and the
#: transfer function's control points (by their bytes): never the view.
_OCCUPIED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _leap_occupancy(txn: VizardTransaction) -> Occupancy | None:
    """``_occupancy(Backend(frame).occupied_blocks(BLOCK))`` of ``txn``'s frame, or None
    where leaping does not apply (MIP, MinIP, X-ray); kept per volume by every other
    input of the occupied-block rule: the datapath (voxel width, sample fraction bits,
    the LUT's shape), the render mode, the iso value and the transfer function's control
    values and RGBA (the LUT is built from them alone).  Scenes with classification or
    geometry features (a multi-field LUT) and transfer functions of another class ask
    the Backend each time."""
    frame = txn.frame
    scene, tf = frame.scene, frame.transfer
    if scene.render.mode not in ("composite", "iso"):
        return None
    features = scene.classification is not None or scene.geometry is not None
    try:
        hash(frame.datapath)
    except TypeError:
        features = True
    if type(tf) is not TransferFunction or features:
        return _occupancy(txn.backend.occupied_blocks(BLOCK))
    points = hashlib.blake2b(digest_size=16)
    for a in (tf.values, tf.rgba):
        points.update(repr((a.shape, a.dtype.str)).encode())
        points.update(np.ascontiguousarray(a).tobytes())
    key = (frame.datapath, scene.render.mode, scene.render.iso_value, points.digest())
    kept = _OCCUPIED.setdefault(frame.volume, {})
    found = kept.get(key)
    if found is None:
        while len(kept) >= _DISTANCES_KEPT:
            kept.pop(next(iter(kept)))
        kept[key] = found = _occupancy(txn.backend.occupied_blocks(BLOCK))
    return found


def _occupancy(occupied: np.ndarray) -> Occupancy:
    """``occupancy_from_ranges(occupied, BLOCK)``, kept by the occupied blocks' shape and
    bits (a digest of every bit: any change of volume, transfer function or datapath
    that moves a block gives another key)."""
    bits = np.packbits(np.ascontiguousarray(occupied, dtype=bool))
    key = (occupied.shape, hashlib.blake2b(bits.tobytes(), digest_size=16).digest())
    found = _DISTANCES.pop(key, None)
    if found is None:
        found = occupancy_from_ranges(occupied, BLOCK)
        while len(_DISTANCES) >= _DISTANCES_KEPT:
            _DISTANCES.pop(next(iter(_DISTANCES)))
    _DISTANCES[key] = found  # the most recent last
    return found


def packet_order(
    ray_ids: np.ndarray, width: int, th: int, tw: int, depth: int
) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`VizardTransaction._packet_order` of rays ``ray_ids`` (flat pixel indices,
    image ``width``) in ``th x tw`` tiles, ``depth`` rays a packet: compiled, a stable
    counting sort by tile of the rays in ``ray_ids`` order, the same order and cuts as
    :func:`packet_order_reference` (``tests/models/test_packet_order_vizard2.py``)."""
    ids = np.ascontiguousarray(ray_ids, dtype=np.int64)
    if not ids.size:
        return np.zeros(0, np.int64), np.zeros(1, np.int64)
    sorted_ids = ids.size < 2 or bool(np.all(ids[1:] > ids[:-1]))
    # Unsorted ids: the counting sort takes the rays in a stable id order, as lexsort.
    perm = np.arange(0) if sorted_ids else np.argsort(ids, kind="stable")
    return _packet_order(ids, perm, width, th, tw, -(-width // tw), depth)


def packet_order_reference(
    ray_ids: np.ndarray, width: int, th: int, tw: int, depth: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`packet_order` in NumPy (the form it replaced, the reference it is held to):
    rays sorted by tile, then by id (``lexsort``), cut every ``depth`` rays of a tile."""
    rows, cols = ray_ids // width, ray_ids % width
    tile = (rows // th) * (-(-width // tw)) + cols // tw
    order = np.lexsort((ray_ids, tile)).astype(np.int64)
    if not order.size:
        return order, np.zeros(1, np.int64)
    tiles = np.concatenate([[0], np.flatnonzero(np.diff(tile[order])) + 1, [order.size]])
    # Each tile's packets start every ``depth`` rays from the tile's first.
    in_tile = np.arange(order.size) - np.repeat(tiles[:-1], np.diff(tiles))
    cuts = np.concatenate([np.flatnonzero(in_tile % depth == 0), [order.size]])
    return order, cuts.astype(np.int64)


@numba.njit(cache=True, nogil=True)
def _packet_order(ids, perm, width, th, tw, tiles_x, depth):  # pragma: no cover - compiled
    n = ids.size
    # Each pixel's tile, row by row (no division a ray: those were most of the time).
    height = ids.max() // width + 1
    of_pixel = np.empty(height * width, np.int64)
    across = np.empty(width, np.int64)  # col // tw
    for col in range(width):
        across[col] = col // tw
    for row in range(height):
        base = (row // th) * tiles_x
        for col in range(width):
            of_pixel[row * width + col] = base + across[col]
    tile = np.empty(n, np.int64)
    top = 0
    for i in range(n):
        tile[i] = of_pixel[ids[i]]
        top = max(top, tile[i])
    start = np.zeros(top + 2, np.int64)
    for i in range(n):
        start[tile[i] + 1] += 1
    for t in range(top + 1):
        start[t + 1] += start[t]
    # Packets: every ``depth`` rays from each tile's first.
    n_cuts = 1
    for t in range(top + 1):
        n_cuts += -(-(start[t + 1] - start[t]) // depth)
    cuts = np.empty(n_cuts, np.int64)
    c = 0
    for t in range(top + 1):
        for at in range(start[t], start[t + 1], depth):
            cuts[c] = at
            c += 1
    cuts[c] = n
    order = np.empty(n, np.int64)
    for k in range(n):
        i = perm[k] if perm.size else k
        order[start[tile[i]]] = i
        start[tile[i]] += 1
    return order, cuts


class VizardTransaction(ReadsTheFrame):
    """SimPy model of one VIZARD II frame at ray-packet granularity.

    Parameters
    ----------
    frame : Frame
        On an architecture of order ``ray``, with the frame's (unleaped) ``ray`` plan; its
        volume and transfer function give the empty space (space leaping) and, when
        ``stopped`` is not set and rays may stop, the functional rung's termination steps.
    pixel_fifo_depth : int, optional
        Override of ``[buffers] pixel_fifo_entries``.
    event_model : bool, optional
        Play the packets in this SimPy model (:meth:`play`) instead of the compiled
        packet model (:mod:`models.machines.vizard2.packet_timing`).
    shared_loop : bool, optional
        Time the frame on the cycle rung's compiled ray loop (shared code, a consistency
        check) instead of the packet model, where the loop holds the frame.
    """

    def __init__(
        self,
        frame: Frame,
        *,
        pixel_fifo_depth: int | None = None,
        event_model: bool = False,
        shared_loop: bool = False,
    ) -> None:
        scene, arch, plan, volume = frame.scene, frame.arch, frame.plan, frame.volume
        self.frame, self.volume, self.datapath = frame, volume, frame.datapath
        self.scene, self.arch, self.planned = scene, arch, plan
        check_frame(frame)
        self.buffers = parse_buffers(arch)
        self.memory = require_pipeline_clock(memory_of(arch), arch)
        self.P = arch.pipelines
        # The Backend's ``mode``, ``ert`` and ``need_grad``, from the same fields and rule
        # (the Backend itself is built only when a path needs it: :attr:`backend`).
        render = scene.render
        mode = render.mode
        stops = render.early_termination < 1.0 if mode == "composite" else mode == "iso"
        self.ert = arch.early_termination and stops
        need_grad = units_needed(scene, frame.transfer.modulates)["gradient"]
        self.event_model, self.shared_loop = event_model, shared_loop
        self.layout = BlockLayout.of(  # the cycle rung's memory image and capacity check
            volume.shape, self.memory.sdram, self.datapath.voxel_bits, need_grad, arch.source
        )
        depth = self.buffers.pixel_fifo_entries
        self.pixel_fifo_depth = depth if pixel_fifo_depth is None else pixel_fifo_depth

    # ------------------------------------------------------------------ set-up

    @functools.cached_property
    def backend(self) -> Backend:
        """The frame's :class:`~models.backend.Backend` (the cycle rung's ray loop, and
        the occupied blocks :func:`_leap_occupancy` does not keep)."""
        return Backend(self.frame)

    @functools.cached_property
    def plan(self) -> SamplePlan:
        """The plan the rays issue (leaped when the machine leaps)."""
        plan = self.planned
        return self._leaped(plan) if self.arch.space_leaping else plan

    def _leaped(self, plan: SamplePlan) -> SamplePlan:
        """Rule 4: rays' first and last samples moved past blocks that cannot give a
        visible sample through this datapath's LUT (or reach the iso value): the cycle
        rung's host geometry, from the same shared helpers."""
        occupancy = _leap_occupancy(self)
        if occupancy is None:
            return plan
        leaped = copy.copy(plan)
        leaped.leap(occupancy)
        return leaped

    def _packets(self) -> list[np.ndarray]:
        """Plan-ray indices per packet: image tiles row-major, rays row-major inside a
        tile, ``ray_queue_entries`` at a time (the ray generator's order)."""
        order, cuts = self._packet_order()
        return [order[lo:hi] for lo, hi in zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True)]

    def _packet_order(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_packets` as one array: plan-ray indices in issue order (int64) and the
        packets' bounds in it (int64, ``packets + 1``)."""
        plan, (th, tw) = self.plan, self.buffers.ray_tile
        depth = self.buffers.ray_queue_entries
        if plan.ray_ids.size and depth <= 0:
            from hwsim.engine.fifo import DeadlockError

            raise DeadlockError(
                f"ray_queue: depth {depth} can never accept a ray; the ray generator waits "
                f"forever with {plan.ray_ids.size} rays pending at cycle 0"
            )
        return packet_order(plan.ray_ids, plan.shape[1], th, tw, depth)

    # ------------------------------------------------------------------ one packet

    def _last_rounds(
        self, packet: np.ndarray, stopped: np.ndarray | None, tags: np.ndarray
    ) -> np.ndarray:
        """Last round each ray of ``packet`` issues: its last planned sample, or with ERT
        hardware its terminating round plus the speculative rounds that start less than
        ``FEEDBACK`` clocks after its terminating sample issued (rule 3).

        The rounds are timed *before* the packet is simulated: ``ceil(live / P)`` issue
        clocks (speculative rays included, by fixed-point iteration) plus, for each lookup
        group that misses when only the non-speculative samples are looked up, the fill's
        unloaded time (CAS latency, its bursts' data clocks, the line write: a row hit,
        the common case).  The cycle rung measures the real, contended stalls instead.
        """
        plan, P = self.plan, self.P
        j_lo, j_hi = plan.j_lo[packet], plan.j_hi[packet]
        if stopped is None:
            return j_hi
        stop = np.minimum(stopped[plan.ray_ids[packet]], j_hi)
        ending = np.flatnonzero(stop < j_hi)
        if not ending.size:
            return j_hi
        j0 = int(j_lo.min())
        rounds = np.arange(j0, int(j_hi.max()) + 1)
        sd = self.memory.sdram
        per_fill = self.layout.value_bursts + self.layout.gradient_bursts
        wide = plan.ray_ids.size + 1
        last = stop.copy()
        t = stop[ending] - j0
        for _ in range(4):  # speculative samples lengthen rounds and may miss: iterate
            # Fill stalls of each lookup group that misses (on a copy of the tags).
            t_idx, index, _, sample, block, line = self._lookups(packet, last)
            miss = self._resolve(tags.copy(), block, line)
            m_sample = sample[miss]
            groups, fills = np.unique(
                t_idx[m_sample] * wide + index[m_sample] // P, return_counts=True
            )
            stall = sd.cas_latency + fills * per_fill * sd.burst_cycles + FILL_WRITE
            g_round, g_clock = groups // wide, groups % wide
            live = (j_lo[:, None] <= rounds) & (rounds <= last[:, None])
            clocks = -(-live.sum(axis=0) // P)
            clocks = clocks + np.bincount(g_round, weights=stall, minlength=rounds.size)
            starts = np.concatenate([[0], np.cumsum(clocks)])
            rank = live[:, t].cumsum(axis=0)[ending, np.arange(ending.size)] - 1
            issue_clock = rank // P
            # Stalls of the round's missing groups at or before the ray's issue clock.
            before = np.array(
                [
                    stall[(g_round == r_k) & (g_clock <= c_k)].sum()
                    for r_k, c_k in zip(t.tolist(), issue_clock.tolist(), strict=True)
                ]
            )
            issued = starts[t] + issue_clock + before
            # Rounds that start before issued + FEEDBACK still issue the ray.
            first_stop = np.searchsorted(starts, issued + FEEDBACK, side="left")
            new = np.minimum(np.maximum(j0 + first_stop - 1, stop[ending]), j_hi[ending])
            if np.array_equal(new, last[ending]):
                break
            last[ending] = new
        return last

    def _lookups(self, packet: np.ndarray, last: np.ndarray):
        """The packet's samples in issue order and their block lookups.

        Returns ``(round of each sample, index in its round, lookup sample, lookup block,
        lookup line)``, lookups sample-major, corners in ``c = 4 dz + 2 dy + dx`` order,
        a corner looked up only when its block differs from the lower corners' (its set
        axes all straddle a block boundary)."""
        plan = self.plan
        j_lo = plan.j_lo[packet]
        j0 = int(j_lo.min())
        rounds = np.arange(j0, int(last.max()) + 1)
        live = (j_lo[:, None] <= rounds) & (rounds <= last[:, None])
        t_idx, ray = np.nonzero(live.T)  # round-major, packet order inside a round
        j = rounds[t_idx]
        zyx = plan.position(j, packet[ray])
        shape = self.volume.shape
        taps = interp_unit.interp_taps(zyx, shape, self.datapath.interp)
        i0 = taps.cells  # (3, n)
        straddle = [(i0[a] % BLOCK == BLOCK - 1) & (shape[a] > 1) for a in range(3)]
        mask = 4 * straddle[0] + 2 * straddle[1] + straddle[2]
        corners = np.arange(8)
        looked = (corners[None, :] & ~mask[:, None]) == 0  # (n, 8)
        sample, corner = np.nonzero(looked)
        nbz, nby, nbx = self.layout.nb
        bz = (i0[0][sample] + ((corner >> 2) & 1)) // BLOCK
        by = (i0[1][sample] + ((corner >> 1) & 1)) // BLOCK
        bx = (i0[2][sample] + (corner & 1)) // BLOCK
        block = (bz * nby + by) * nbx + bx
        sz, sy, sx = self.buffers.cache_sets
        line = ((bz % sz) * sy + by % sy) * sx + bx % sx
        counts = live.sum(axis=0)
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        index = np.arange(t_idx.size) - first[t_idx]
        return t_idx, index, counts, sample, block, line

    def _resolve(self, tags: np.ndarray, block: np.ndarray, line: np.ndarray) -> np.ndarray:
        """Hit or miss of each lookup, in order, on the direct-mapped tags (updated)."""
        order = np.argsort(line, kind="stable")
        s_line, s_tag = line[order], block[order]
        first = np.ones(s_line.size, dtype=bool)
        first[1:] = s_line[1:] != s_line[:-1]
        prev = np.empty(s_line.size, dtype=np.int64)
        prev[1:] = s_tag[:-1]
        prev[first] = tags[s_line[first]]
        miss = np.empty(s_line.size, dtype=bool)
        miss[order] = prev != s_tag
        last = np.ones(s_line.size, dtype=bool)
        last[:-1] = first[1:]
        tags[s_line[last]] = s_tag[last]
        return miss

    def _fill_bursts(self, m_clock: np.ndarray, blocks: np.ndarray):
        """The packet's miss groups ``(clock in the packet, banks, rows)``: each group's
        fills' bursts, sorted page by page (bank, then row, stable) as the fill sequencer
        sends them; computed for the whole packet at once."""
        if not m_clock.size:
            return [], 0
        cuts = np.flatnonzero(np.diff(m_clock)) + 1
        group = np.zeros(m_clock.size, dtype=np.int64)
        group[cuts] = 1
        group = np.cumsum(group)
        banks, rows = self.layout.bursts(blocks)
        per_fill = banks.size // blocks.size
        of_burst = np.repeat(group, per_fill)
        order = np.lexsort((rows, banks, of_burst))
        banks, rows = banks[order].tolist(), rows[order].tolist()
        bounds = np.concatenate([[0], cuts, [m_clock.size]]) * per_fill
        starts = m_clock[np.concatenate([[0], cuts])].tolist()
        out = [
            (clock, banks[lo:hi], rows[lo:hi])
            for clock, lo, hi in zip(starts, bounds[:-1].tolist(), bounds[1:].tolist(), strict=True)
        ]
        return out, len(banks)

    # ------------------------------------------------------------------ frame

    def run(self) -> TxnTiming:
        """Time the frame: on the compiled packet model (:class:`PacketTiming`, the
        machine's rules written again, coarser) unless ``event_model`` or
        ``shared_loop`` asks otherwise or the model refuses the frame; then on the cycle
        rung's compiled ray loop without its datapath where that loop holds the frame
        (shared code: a consistency check, not independent evidence), else in this
        SimPy model (:meth:`play`)."""
        if self.event_model:
            return self.play()
        refused = None
        if not self.shared_loop:
            model = PacketTiming(self)
            refused = model.refusal()
            if refused is None:
                start = time.perf_counter()
                cycles, counters = model.run()
                counters["transaction.granularity"] = "packets, rounds and page runs (compiled)"
                counters["transaction.timing_seconds"] = time.perf_counter() - start
                return TxnTiming(cycles, counters)
        timed = self._on_the_ray_loop() or self.play()
        if refused is not None:
            timed.counters["transaction.packet_model_refused"] = refused
        return timed

    def _on_the_ray_loop(self) -> TxnTiming | None:
        """``VizardMachine.timing`` on this frame; None out of the loop's scope."""
        from models.machines.vizard2.cycle import VizardMachine  # the cycle rung's loop

        start = time.perf_counter()
        faults = VizardFaults(pixel_fifo_depth=self.pixel_fifo_depth)
        counters = VizardMachine(self.backend, faults=faults).timing(
            lambda done, total: report_progress(self, done, total)
        )
        if counters is None:
            return None
        counters["pipeline.latency_cycles"] = FEEDBACK
        counters["transaction.granularity"] = "the cycle rung's ray loop, timing only"
        counters["transaction.timing_seconds"] = time.perf_counter() - start
        return TxnTiming(int(counters["frame.cycles"]), counters)

    def play(self) -> TxnTiming:
        """Simulate the frame in the SimPy event model; return its cycles and the
        model's counters."""
        start = time.perf_counter()
        stopped = self.termination_steps(self.frame) if self.ert else None
        P = self.P
        env = simpy.Environment()
        port = SdramTransactionPort(env, self.memory.sdram)
        ctl = port.controller
        bus = PixelBus(env, self.pixel_fifo_depth, self.buffers.ray_queue_entries)
        tags = np.full(self.buffers.cache_lines, -1, dtype=np.int64)
        stats = {"lookups": 0, "fills": 0, "issued": 0, "speculative": 0, "events": 0}
        stats["groups"] = stats["pipe_end"] = stats["stall"] = 0
        packets = self._packets()

        def issue():
            for k, packet in enumerate(packets):
                last = self._last_rounds(packet, stopped, tags)
                if stopped is not None:
                    stop = np.minimum(stopped[self.plan.ray_ids[packet]], last)
                    stats["speculative"] += int((last - stop).sum())
                t_idx, index, counts, sample, block, line = self._lookups(packet, last)
                miss = self._resolve(tags, block, line)
                stats["lookups"] += block.size
                stats["fills"] += int(miss.sum())
                stats["issued"] += t_idx.size
                clocks = -(-counts // P)
                round_start = np.concatenate([[0], np.cumsum(clocks)])
                begin, waited = env.now, 0
                m_sample = sample[miss]
                # Lookup group of each miss: its sample's clock in the packet.
                m_clock = round_start[t_idx[m_sample]] + index[m_sample] // P
                groups, bursts = self._fill_bursts(m_clock, block[miss])
                for clock, banks, rows in groups:
                    arrive = begin + clock + waited
                    if arrive > env.now:
                        yield env.timeout(arrive - env.now)
                    # The port's read (hwsim.memory.SdramTransactionPort.read) without
                    # re-validating the lists the layout built, as slab_timing does.
                    first = len(ctl)
                    ctl._run(banks, rows, [int(env.now)] * len(banks))
                    ready = ctl.data_end(first + len(banks) - 1) + FILL_WRITE
                    yield env.timeout(ready - env.now)
                    waited += int(env.now - arrive)
                    stats["events"] += 2
                stats["groups"] += len(groups)
                stats["stall"] += waited
                end = begin + int(round_start[-1]) + waited
                if end > env.now:
                    yield env.timeout(end - env.now)
                yield from bus.push(int(packet.size))  # the packet retires
                stats["events"] += 2
                report_progress(self, k + 1, len(packets))
            stats["pipe_end"] = int(env.now)

        env.process(issue())
        env.run()
        end = max(stats["pipe_end"], bus.end)
        cycles = end + FEEDBACK
        sched = port.schedule()
        counters: dict[str, Any] = {k: int(v) for k, v in sched.stats.to_counters("memory").items()}
        counters.update(
            {
                "cache.lines": self.buffers.cache_lines,
                "cache.lookups": stats["lookups"],
                "cache.hits": stats["lookups"] - stats["fills"],
                "cache.misses": stats["fills"],
                "cache.fills": stats["fills"],
                "cache.miss_groups": stats["groups"],
                "memory.stall_cycles": stats["stall"],
                "ray_generator.rays": int(self.plan.ray_ids.size),
                **bus.counters(stats["pipe_end"]),
                "pipeline.latency_cycles": FEEDBACK,
                "frame.cycles": cycles,
                "frame.issued_samples": stats["issued"],
                "ert.speculative_samples": stats["speculative"],
                "frame.planned_samples": self.planned.samples,
                "frame.leaped_samples": self.planned.samples - self.plan.samples,
                "transaction.events": stats["events"] + bus.events,
                "transaction.granularity": f"packets of {self.buffers.ray_queue_entries} rays",
                "transaction.timing_seconds": time.perf_counter() - start,
            }
        )
        return TxnTiming(int(cycles), counters)
