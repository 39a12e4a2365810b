"""The VolumePro-family frame timing's beam and delivery loop, compiled (numba).

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rules 1-9 (the rules
#      :func:`models.machines.volumepro.slab_timing.run_timing` states and plays in Python).

:func:`play` runs the same loop as the reference path of
:func:`~models.machines.volumepro.slab_timing.run_timing` -- beams in processing order,
each waiting for its last needed delivery, deliveries issued in read order to every
module's SDRAM controller once the input buffer has room -- with the controllers' state
stacked in arrays and each burst batch scheduled by the same compiled request loop
(:func:`hwsim.memory.sdram_kernel.schedule_requests`), so a delivery costs no Python call.
One call per sample slice; the pixel-bus FIFO between slices stays the engine's
:class:`~hwsim.engine.DrainFifo`.  The controllers get their state back at the end, so their
schedules (counters, waveform) are the reference path's, bit for bit (tests/models/
test_cycle_fused.py compares whole frames both ways).
"""

from __future__ import annotations

from itertools import chain

import numba
import numpy as np

from hwsim.engine import DeadlockError
from hwsim.memory.sdram_kernel import REGS, schedule_requests

__all__ = ["play", "play_once"]

# Registers of the loop state ``st``.
T, G, BI, STALL, STATUS, INFO = range(6)
NEVER_READ, BUFFER_FULL, LOGS_FULL = 1, 2, 3
BOOKED, REFRESHES = REGS.index("booked"), REGS.index("refreshes")


@numba.njit(cache=True, nogil=True)
def _deliver(st, ctl, table, ends, ready, capacity, ratio, tail, deskew):
    """Issue delivery ``st[G]`` on every module (``deliver`` of the reference loop);
    False with ``st[STATUS]`` set when it cannot."""
    params, regs, bank_state, out, arrivals, n_req, booked, logs, scratch = ctl
    banks, rows, starts, free_after = table
    g = st[G]
    if g >= free_after.shape[0]:
        st[STATUS] = NEVER_READ
        return False
    earliest = 0
    if g >= capacity:
        f = free_after[g - capacity]
        if f >= st[BI]:
            st[STATUS], st[INFO] = BUFFER_FULL, f
            return False
        earliest = ends[f]
    e_mem = np.int64(np.ceil(earliest * ratio))
    last = 0
    for k in range(regs.shape[0]):
        a, b = starts[k, g], starts[k, g + 1]
        if a == b:
            continue
        i0 = n_req[k]
        scratch[0] = e_mem  # the batch's first burst waits for the buffer, the rest follow
        arrivals[k, i0] = e_mem
        grown_booked, grown_log = schedule_requests(
            params, regs[k], bank_state[k], banks[a:b], rows[a:b], scratch[: b - a],
            out[k], i0, booked[k], logs[k],
        )  # fmt: skip
        scratch[0] = 0
        if grown_booked.shape[0] != booked.shape[1] or grown_log.shape[0] != logs.shape[1]:
            st[STATUS] = LOGS_FULL  # the caller starts again with room to spare
            return False
        n_req[k] = i0 + (b - a)
        last = max(last, out[k, 0, i0 + (b - a) - 1] + tail)
    ready[g] = np.int64(np.ceil(last / ratio)) + deskew
    st[G] = g + 1
    return True


@numba.njit(cache=True, nogil=True)
def _beams(
    st, needs, cycles, flush, params, regs, bank_state, out, arrivals, n_req, booked, logs,
    scratch, banks, rows, starts, free_after, ends, ready, capacity, ratio, tail, deskew,
):  # fmt: skip
    """One slice's beams (or, ``flush``, the reads no beam waits for)."""
    ctl = (params, regs, bank_state, out, arrivals, n_req, booked, logs, scratch)
    table = (banks, rows, starts, free_after)
    t = st[T]
    for i in range(needs.shape[0]):
        need = needs[i]
        while need >= st[G]:
            if not _deliver(st, ctl, table, ends, ready, capacity, ratio, tail, deskew):
                return
        begin = t if need < 0 or ready[need] <= t else ready[need]
        st[STALL] += begin - t
        t = begin + cycles[i]
        ends[st[BI]] = t
        st[BI] += 1
    st[T] = t
    if flush:
        while st[G] < table[3].shape[0]:
            if not _deliver(st, ctl, table, ends, ready, capacity, ratio, tail, deskew):
                return


def _stacked(controllers, room: tuple[int, int], requests: list[int], narrow: bool = False):
    """The controllers' state as arrays the loop indexes by module, with room for
    ``requests[k]`` more requests of module ``k`` and ``room`` booked commands and
    refreshes per module (plain arrays: a numba typed list costs seconds to compile in
    every process).  The controllers are not reserved first: their arrays and these
    would be two copies of 40 bytes a burst (1.4 GB over a 512^3 frame's ~17 M).
    ``narrow``: the per-request cycles held as int32 (20 bytes a burst; :func:`_wrapped`
    tells whether a frame outgrew them)."""
    M = len(controllers)
    n_max = max(max(c._n + r, c._n, 1) for c, r in zip(controllers, requests, strict=True))
    dtype = np.int32 if narrow else np.int64
    out = np.zeros((M, 4, n_max), dtype=dtype)
    arrivals = np.zeros((M, n_max), dtype=dtype)
    fill = [(int(c._regs[BOOKED]), int(c._regs[REFRESHES])) for c in controllers]
    booked = np.zeros((M, max(room[0], *(b for b, _ in fill), 1)), np.int64)
    logs = np.zeros((M, max(room[1], *(r for _, r in fill), 1), 2), np.int64)
    for k, (c, (b, r)) in enumerate(zip(controllers, fill, strict=True)):
        out[k, :, : c._n] = c._out[:, : c._n]
        arrivals[k, : c._n] = c._arrivals[: c._n]
        booked[k, :b] = c._booked[:b]
        logs[k, :r] = c._log[:r]
    return (
        controllers[0]._params,
        np.stack([c._regs for c in controllers]),
        np.stack([c._banks for c in controllers]),
        out,
        arrivals,
        np.array([c._n for c in controllers], dtype=np.int64),
        booked,
        logs,
    )


def _unstack(controllers, ctl) -> None:
    _, regs, bank_state, out, arrivals, n_req, booked, logs, _ = ctl
    for k, c in enumerate(controllers):
        c._regs[:] = regs[k]
        c._banks[:] = bank_state[k]
        c._out, c._arrivals = out[k], arrivals[k]
        c._booked, c._log, c._n = booked[k], logs[k], int(n_req[k])


def play(
    table, slices, make_controllers, *, capacity, pixel_fifo, out, ends, ready, tail, ratio,
    deskew=0,
):  # fmt: skip
    """Run the frame's slices and deliveries (``run_timing``'s loop) on the controllers
    ``make_controllers()`` returns (sized here for their requests); fills ``out`` (a
    ``FrameTiming``), ``ends`` and ``ready`` as the reference loop does and returns the
    controllers.

    The command-bus and refresh logs are sized up front (a refresh per ``t_refi`` of the
    beams' or the bursts' time, whichever is longer, twice over); a frame that needs more
    starts again from fresh controllers with twice the room, so the logs never grow inside
    the loop."""
    controllers = make_controllers()
    room = first_room(table, slices, controllers[0].cfg, ratio)
    fifo = dict(vars(pixel_fifo))  # its state at the frame's start, for a new attempt
    narrow = table.bursts(0) > NARROW_FROM  # a large frame's cycles fit in int32 (checked)
    while True:
        done = _play(table, slices, controllers, room, capacity, pixel_fifo, out, ends, ready,
                     tail, ratio, narrow, deskew)  # fmt: skip
        if done and not (narrow and _wrapped(controllers)):
            return controllers
        if done:
            narrow = False  # a cycle outgrew int32: the frame again, wide
        else:
            room = (2 * room[0], 2 * room[1])
        controllers = make_controllers()
        out.blocks.clear()
        out.memory_stall = out.pixel_stall = 0
        vars(pixel_fifo).update(fifo)


def play_once(
    table, slices, controllers, room, *, capacity, pixel_fifo, out, ends, ready, tail, ratio,
    deskew=0,
) -> bool:  # fmt: skip
    """One attempt of :func:`play` with ``room`` given, on ``slices`` as they come (an
    iterable: each is played once taken, so a thread can play a frame's slices while the
    frame makes the later ones): False when the logs ran out of room or a cycle outgrew
    int32 (then :func:`play` on fresh controllers and state gives the frame)."""
    narrow = table.bursts(0) > NARROW_FROM
    done = _play(table, slices, controllers, room, capacity, pixel_fifo, out, ends, ready,
                 tail, ratio, narrow, deskew)  # fmt: skip
    return done and not (narrow and _wrapped(controllers))


#: Bursts on module 0 from which a frame's per-request cycles are held as int32 (a
#: 512^3 frame's ~4 M per module: 0.34 GB less at its memory peak); below, int64.
NARROW_FROM = 1 << 20


def _wrapped(controllers) -> bool:
    """Whether a module's READ cycles left int32 (they start at 0 or later and grow by
    at least a burst per request, so a wrap shows as a negative cycle or a step that
    does not grow; the steps taken in int64)."""
    for c in controllers:
        reads = c._out[0, : c._n].astype(np.int64)
        if (reads < 0).any() or (np.diff(reads) <= 0).any():
            return True
    return False


def first_room(table, slices, cfg, ratio: float) -> tuple[int, int]:
    """Booked commands and refreshes per module to make room for before the loop runs."""
    beam_clocks = sum(int(s.cycles.sum()) + s.extra + s.pre for s in slices)
    bursts = max((table.bursts(k) for k in range(table.starts.shape[0])), default=0)
    span = max(beam_clocks * ratio, bursts * cfg.burst_cycles)
    return 64 + 4 * cfg.queue_depth, 64 + 2 * int(span // max(cfg.t_refi, 1))


def _play(table, slices, controllers, room, capacity, pixel_fifo, out, ends, ready, tail, ratio,
          narrow, deskew):  # fmt: skip
    """One attempt of :func:`play`: False when the logs ran out of room (``slices``: any
    iterable)."""
    scratch = np.zeros(max(int(np.diff(table.starts, axis=1).max(initial=0)), 1), np.int64)
    requests = [table.bursts(k) for k in range(len(controllers))]
    ctl = (*_stacked(controllers, room, requests, narrow), scratch)
    tab = (table.banks, table.rows, table.starts, table.free_after)
    st = np.zeros(6, dtype=np.int64)
    for work in chain(slices, (None,)):
        flush = work is None
        start_block = int(st[T])
        st[T] += 0 if flush else work.pre
        st[STALL] = 0
        needs = np.zeros(0, np.int64) if flush else work.needs
        cycles = needs if flush else work.cycles
        _beams(st, needs, cycles, flush, *ctl, *tab, ends, ready, capacity, ratio, tail, deskew)
        if st[STATUS] == LOGS_FULL:
            return False
        if st[STATUS]:
            _raise(st, capacity)
        if flush:
            break
        t = int(st[T]) + work.extra
        pix = pixel_fifo.advance(t - start_block, work.arrivals, start_block)
        st[T] = t + pix
        out.memory_stall += int(st[STALL])
        out.pixel_stall += pix
        out.blocks.append((int(st[T]) - start_block, int(st[STALL]) + pix + work.pre))
    out.end = int(st[T])
    _unstack(controllers, ctl)
    return True


def _raise(st, capacity: int) -> None:
    g, bi, f = int(st[G]), int(st[BI]), int(st[INFO])
    if st[STATUS] == NEVER_READ:
        raise DeadlockError(f"a beam needs delivery {g}, which the memory never reads")
    raise DeadlockError(
        f"input buffer: {capacity} mini-block beams cannot hold the sample "
        f"window; delivery {g} waits for beam {f} to free a slot while the "
        f"pipelines wait for it at beam {bi}"
    )
