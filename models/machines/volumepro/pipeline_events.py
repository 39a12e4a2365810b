"""VolumePro's transaction rung as events: the memory and pipelines processes.

# Ref: docs/transaction.md (VolumePro rules 1-8); models/machines/volumepro/transaction.py
#      (:class:`SlabTransaction`, which prepares the beam groups, chunks and loads).

:func:`simulate` runs a frame's (or ``frames`` back-to-back frames') beam groups and
chunk reads: on the compiled event loop (:mod:`models.machines.volumepro.pipeline_kernel`)
where it holds the frame, else on the generator processes here, driven by
:class:`~models.machines.volumepro.event_loop.EventLoop` (SimPy's event order, lean) or
by SimPy itself (``events="simpy"``, the reference the other two are tested against:
``tests/models/test_event_loop.py``).
"""

from __future__ import annotations

import operator

import numpy as np
import simpy

from hwsim.engine.fifo import DeadlockError
from hwsim.memory import SdramTransactionPort
from models.machines.common.pixel_bus import PixelBus
from models.machines.volumepro.chunk_reads import (
    ChunkLink,
    DeferredReads,
    chunk_streams,
    memory_process,
)
from models.machines.volumepro.event_loop import EventLoop
from models.machines.volumepro.fifo_timing import DESKEW_WRITE

__all__ = ["pipelines_process", "sdram_ports", "simulate"]


def sdram_ports(env, txn) -> list[SdramTransactionPort]:
    """The rung's SDRAM ports, one a module: the one place it hands its SDRAM parameters
    to the (shared) controller, for the generator processes and the compiled loop alike
    (the evidence tests mutate the parameters here)."""
    return [SdramTransactionPort(env, txn.memory.sdram) for _ in range(txn.memory.modules)]


def simulate(txn, chunks, groups, free_after, cap, loads, *, frames):
    """Run the memory and the pipelines over ``frames`` identical frames back to back
    (the same controllers, buffer and pixel FIFO carry on); returns the statistics
    (``pipe_ends``: when each frame's pipelines finished), the pixel bus and the
    deferred reads (their SDRAM ``ports``).

    Both processes keep their own clock ahead of SimPy's and yield only where they
    wait on each other or on the pixel bus (:func:`pipelines_process`,
    :func:`~models.machines.volumepro.chunk_reads.memory_process`): the same cycles as
    an event per beam group and per chunk, far fewer events."""
    if (
        txn.events == "compiled"
        and not txn.slice_fifo
        and len(txn.bands) == 1
        and getattr(txn, "progress", None) is None
    ):
        from models.machines.volumepro.pipeline_kernel import simulate as compiled  # numba

        return compiled(txn, chunks, groups, free_after, cap, *loads, frames=frames)
    nc, ng = len(chunks), len(groups)
    # Frame f's chunk c is chunk f nc + c, its group k group f ng + k.
    free_after = np.concatenate(
        [np.where(free_after >= 0, free_after + f * ng, -1) for f in range(frames)]
    )
    env = simpy.Environment() if txn.events == "simpy" else EventLoop()
    ports = sdram_ports(env, txn)
    link = ChunkLink(env, DeferredReads(ports, chunk_streams(txn, chunks), nc, frames), nc * frames)
    frees_at: dict[int, list[int]] = {}
    for c, g in enumerate(free_after.tolist()):
        frees_at.setdefault(g, []).append(c)
    for c in frees_at.pop(-1, []):  # no group needs it: free from the start
        link.free_at[c] = 0
    bus = PixelBus(env, txn.pixel_fifo_depth, txn.row_pixels)
    stats = {"events": 0, "stall": 0, "buffer_full": 0, "stretch": 0, "pipe_end": 0}
    stats["section"] = 0
    stats["pipe_ends"] = []
    env.process(memory_process(link, cap, stats))
    env.process(
        pipelines_process(
            txn,
            link,
            groups,
            free_after,
            frees_at,
            cap,
            frames,
            bus,
            stats,
            loads,
        )
    )
    env.run()
    link.reads.flush(link.reads.issued_count)  # bursts of chunks no group waited on
    if stats["pipe_end"] == 0 and groups:
        raise DeadlockError("the pipelines never finished: the input buffer is too small")
    return stats, bus, link.reads


def pipelines_process(txn, link, groups, free_after, frees_at, cap, frames, bus, stats, loads):
    """The pipelines process: beam group after beam group on its own clock ``t``,
    syncing SimPy's to it only to wait for a chunk not ready by then and to push
    pixels (the pixel bus runs on SimPy's clock)."""
    busiest, beam_clocks, by_band, parked = loads
    env, reads, ready_at = link.env, link.reads, link.reads.ready
    n_steps, nc, ng = len(busiest), link.total // frames, len(groups)
    deskew = DESKEW_WRITE if txn.slice_fifo else 0  # rule 3': usable a clock later
    firsts, mores = _slice_bounds(groups)
    # Sections are parallel-only, where a slice never has more samples than voxels:
    # the perspective stretch applies to the unsectioned frame.
    single = len(txn.bands) == 1
    stretches = np.maximum(busiest - beam_clocks, 0).tolist() if single else [0] * n_steps
    leaving = by_band.tolist()  # rays leaving after each slice of each band
    for bi, rays in enumerate(parked.tolist()):
        if n_steps:
            leaving[bi][n_steps - 1] += rays  # and the rays the band parked
    slice_fifo, overhead = txn.slice_fifo, txn.arch.slice_overhead_cycles
    frees, free_at, done = frees_at.get, link.free_at, txn._slices_done
    progress = getattr(txn, "progress", None)
    section_overhead = txn.arch.section_overhead_cycles
    t = events = 0
    for f in range(frames):
        k0, c0 = f * ng, f * nc  # the frame's first group and chunk
        for kg, (bi, j, clocks, need) in enumerate(groups):
            k = k0 + kg
            if need >= 0:
                need += c0
            first = firsts[kg]
            if bi and first and groups[kg - 1][0] != bi:
                # Section change: overhead, then reload the rays parked by the last band.
                pre = section_overhead + int(parked[bi - 1])
                stats["section"] += pre
                t += pre
            # (ready_at[need]: flushed already; else ask, which flushes the reads issued)
            if need >= 0 and not (
                ready_at[need] <= t - deskew
                if need < len(ready_at)
                else reads.ready_by(need, t - deskew)
            ):
                yield from link.sync(t)
                if not reads.ready_by(need, t - deskew):
                    if need - cap >= 0 and free_after[need - cap] >= k:
                        raise DeadlockError(
                            f"input buffer: {txn.capacity_mbbs} mini-block beams cannot "
                            f"hold the sample window of slice {j}"
                        )
                    if not reads.issued(need):
                        link.waiting[:] = [need, env.event()]
                        yield link.waiting[1]
                    # The memory process may not have run since the slot it waited on
                    # was freed: a chunk it issues now at an earlier cycle may be ready
                    # by t (no stall).
                    ready = max(t, reads.ready_at(need) + deskew)
                    stats["stall"] += ready - t
                    t = ready
            if slice_fifo and first and j >= 0:  # rule 8': from the period's start
                yield from link.sync(t)
                yield from bus.push(leaving[bi][j])
                t = int(env.now)
            t += clocks
            events += 2
            for c in frees(k, ()):  # ChunkLink.free, written out
                free_at[c] = t
                waits = link.memory_waits
                if waits[0] == c:
                    waits[0] = -1
                    waits[1].succeed()
            if mores[kg] or j < 0:
                continue  # more beam groups of this slice; a read-only period (rule 3')
            stats["stretch"] += stretches[j]
            t += overhead + stretches[j]
            if not slice_fifo:  # rule 8: the slice's pixels at its end
                yield from link.sync(t)
                yield from bus.push(leaving[bi][j])
                t = int(env.now)
            done[0] += 1
            if progress is not None:  # report_progress, written out
                progress(*done)
            if kg == ng - 1:
                stats["pipe_ends"].append(t)
    stats["events"] += events
    stats["pipe_end"] = t


def _slice_bounds(groups) -> tuple[list[bool], list[bool]]:
    """Per beam group ``(band, j, ...)``: whether it is its slice's first, and whether
    another group of its slice follows."""
    keys = [g[:2] for g in groups]
    firsts = [True, *map(operator.ne, keys[1:], keys)] if keys else []
    return firsts, [not f for f in firsts[1:]] + [False]
