"""The VolumePro 1000 event model's three processes as one compiled event loop (numba).

# Ref: models/machines/volumepro/pipeline_events.py (pipelines_process),
#      chunk_reads.memory_process and models/machines/common/pixel_bus.py (PixelBus):
#      the rules written again; event_loop.py (SimPy's order).

:func:`run_processes` plays the pipelines, the memory and the pixel bus of a frame whose
slices are not sectioned and whose pipelines read no slice FIFOs (VolumePro 1000) with
the same events, in SimPy's order, as the generator processes on
:class:`~models.machines.volumepro.event_loop.EventLoop`: the queue holds ``(time,
priority, sequence)`` and a handler per event (a process's start URGENT, every other
NORMAL, a tie to the event scheduled first), so the pixel bus's batches, its peak
occupancy and every cycle come out the same.  Each process is a state machine whose
phases are the places its generator yields:

* pipelines (``P``): beam group after beam group on their own clock; a group whose chunk
  is not ready by then syncs (a timeout to its clock), checks again, waits for the
  memory to issue the chunk if it has not, and stalls to its readiness; a slice's end
  syncs and pushes its pixels a batch at a time (a put event each, admitted now if the
  FIFO has room, else when a get frees it), waking the bus after each put;
* memory (``M``): chunk runs at the later of the last issue and their slot's freeing,
  waiting (an event the pipelines trigger on freeing) for a slot not freed yet;
* pixel bus (``D``): batches of at most ``batch`` pixels, a timeout of a clock a pixel,
  then the get (its admission of a waiting put before the bus goes on).

The SDRAM reads stay in Python (:class:`~models.machines.volumepro.chunk_reads.
DeferredReads`): when the pipelines ask for the readiness of a chunk issued but not yet
handed to the ports, the loop returns :data:`NEED_FLUSH` with its state kept, the caller
flushes and calls again (the controller is causal: the split changes no cycle).
``tests/models/test_pipeline_kernel.py`` holds it to the generator processes.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["DONE", "ERR_BUFFER", "ERR_PIXEL", "NEED_FLUSH", "new_state", "run_processes"]

DONE, NEED_FLUSH, ERR_BUFFER, ERR_PIXEL = 0, 1, 2, 3

# Event kinds (their handler).
_P, _M, _D_WORK, _D_TIMEOUT, _D_GET, _D_START = 0, 1, 2, 3, 4, 5
# Pipelines phases (where the generator resumes).
_GROUP, _SYNCED, _WAITED, _RUN, _PUSH, _PUT, _PUT_DONE, _END = 0, 1, 2, 3, 4, 5, 6, 7
_FINISHED = 8

#: State registers (``st``).
ST = (
    "now", "seq", "n_q",  # clock, scheduling count, queued events
    "p_phase", "p_k", "p_t", "p_need", "p_events", "p_left", "p_chunk", "p_waited",
    "p_active", "p_wait_need",  # P mid-run (resume first), the chunk P waits to issue
    "m_g", "m_now", "m_wait", "m_done",  # memory: next chunk, its clock, slot awaited
    "level", "work_triggered", "d_chunk", "put_waiting",  # pixel FIFO and bus
    "pushed", "sent", "max_occ", "bus_stall", "bus_events", "bus_end",
    "stall", "buffer_full", "stretch", "events", "pipe_end", "n_issued", "n_flushed",
    "err_a", "err_b", "started",
)  # fmt: skip
_I = {name: i for i, name in enumerate(ST)}
NOW, SEQ, NQ = 0, 1, 2
P_PHASE, P_K, P_T, P_NEED, P_EVENTS, P_LEFT, P_CHUNK, P_WAITED = 3, 4, 5, 6, 7, 8, 9, 10
P_ACTIVE, P_WAIT_NEED = 11, 12
M_G, M_NOW, M_WAIT, M_DONE = 13, 14, 15, 16
LEVEL, WORK_TRIGGERED, D_CHUNK, PUT_WAITING = 17, 18, 19, 20
PUSHED, SENT, MAX_OCC, BUS_STALL, BUS_EVENTS, BUS_END = 21, 22, 23, 24, 25, 26
STALL, BUFFER_FULL, STRETCH, EVENTS, PIPE_END, N_ISSUED, N_FLUSHED = (
    27, 28, 29, 30, 31, 32, 33,
)  # fmt: skip
ERR_A, ERR_B, STARTED = 34, 35, 36
assert len(ST) == 37 and _I["started"] == STARTED


def new_state() -> tuple[np.ndarray, np.ndarray]:
    """Registers (``st``, :data:`ST`) and the event queue (``q``: rows time, priority,
    sequence, kind) of a loop not yet started."""
    st = np.zeros(len(ST), dtype=np.int64)
    st[P_WAIT_NEED] = st[M_WAIT] = -1
    return st, np.zeros((4, 16), dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def _schedule(st, q, delay, priority, kind):
    n = st[NQ]
    q[0, n], q[1, n], q[2, n], q[3, n] = st[NOW] + delay, priority, st[SEQ], kind
    st[SEQ] += 1
    st[NQ] = n + 1


@numba.njit(cache=True, nogil=True)
def _pop(st, q):
    """The next event (least time, priority, sequence): its kind; -1 when none."""
    n = st[NQ]
    if n == 0:
        return -1
    b = 0
    for i in range(1, n):
        if (q[0, i], q[1, i], q[2, i]) < (q[0, b], q[1, b], q[2, b]):
            b = i
    st[NOW] = q[0, b]
    kind = q[3, b]
    for r in range(4):
        q[r, b] = q[r, n - 1]
    st[NQ] = n - 1
    return kind


@numba.njit(cache=True, nogil=True)
def _memory(st, q, free_at, issue_at, batches, cap, total, nc):
    """The memory process from where it waited (or its start) to its next wait or end."""
    g, now = st[M_G], st[M_NOW]
    while g < total:
        if g >= cap:
            if free_at[g - cap] < 0:  # the pipelines have not freed it yet
                st[M_WAIT] = g - cap
                st[M_G], st[M_NOW] = g, now
                return
            if free_at[g - cap] > now:
                st[BUFFER_FULL] += free_at[g - cap] - now
                now = free_at[g - cap]
        h = g + 1
        while h < total and (h < cap or 0 <= free_at[h - cap] <= now):
            h += 1
        events = h - g
        for c in range(g, h):
            issue_at[c] = now
            events += batches[c % nc]
        st[EVENTS] += events
        st[N_ISSUED] = h
        g = h
        if st[P_WAIT_NEED] >= 0 and st[P_WAIT_NEED] < h:
            _schedule(st, q, 0, 1, _P)
            st[P_WAIT_NEED] = -1
    st[M_G], st[M_NOW], st[M_DONE] = g, now, 1


@numba.njit(cache=True, nogil=True)
def _drain(st, q, batch):
    """The bus from a resumption to its next wait: a batch's timeout, or the work event
    when the FIFO is empty."""
    if st[LEVEL] == 0:
        st[WORK_TRIGGERED] = 0  # a new work event, pending
        return
    st[D_CHUNK] = min(st[LEVEL], batch)
    _schedule(st, q, st[D_CHUNK], 1, _D_TIMEOUT)


@numba.njit(cache=True, nogil=True)
def _ready_state(st, ready, c, now):
    """``DeferredReads.ready_by(c, now)``: 1 ready, 0 not, -1 a flush is needed first."""
    if c >= st[N_ISSUED]:
        return 0
    if c >= st[N_FLUSHED]:
        return -1
    return 1 if ready[c] <= now else 0


@numba.njit(cache=True, nogil=True)
def _pipelines(
    st, q, groups, mores, frees, free_ptr, free_after, free_at, ready, loads, dims, pipe_ends
):
    """The pipelines from where they stopped to their next wait (0), a flush (1), their
    end (0, phase finished) or an error (2 buffer, 3 pixel FIFO)."""
    stretches, leaving = loads[0], loads[1]
    cap, ng, frames, nc, depth, capacity, batch, overhead = dims
    while True:
        phase, k = st[P_PHASE], st[P_K]
        if phase == _FINISHED:
            return 0
        kg = k % ng
        j, clocks = groups[kg, 1], groups[kg, 2]
        if phase == _GROUP:
            need = groups[kg, 3]
            if need >= 0:
                need += (k // ng) * nc
            st[P_NEED] = need
            if need < 0:
                st[P_PHASE] = _RUN
                continue
            r = _ready_state(st, ready, need, st[P_T])
            if r < 0:
                return 1
            if r == 1:
                st[P_PHASE] = _RUN
                continue
            st[P_PHASE] = _SYNCED
            if st[P_T] > st[NOW]:
                _schedule(st, q, st[P_T] - st[NOW], 1, _P)
                return 0
            continue
        if phase == _SYNCED:
            need = st[P_NEED]
            r = _ready_state(st, ready, need, st[P_T])
            if r < 0:
                return 1
            if r == 1:
                st[P_PHASE] = _RUN
                continue
            if need - cap >= 0 and free_after[need - cap] >= k:
                st[ERR_A] = j
                return 2
            st[P_PHASE] = _WAITED
            if need >= st[N_ISSUED]:
                st[P_WAIT_NEED] = need
                return 0
            continue
        if phase == _WAITED:
            need = st[P_NEED]
            if need >= st[N_FLUSHED]:
                return 1
            t = max(st[P_T], ready[need])
            st[STALL] += t - st[P_T]
            st[P_T] = t
            st[P_PHASE] = _RUN
            continue
        if phase == _RUN:
            t = st[P_T] + clocks
            st[P_T] = t
            st[P_EVENTS] += 2
            for i in range(free_ptr[k], free_ptr[k + 1]):
                c = frees[i]
                free_at[c] = t
                if st[M_WAIT] == c:
                    st[M_WAIT] = -1
                    _schedule(st, q, 0, 1, _M)
            if mores[kg] or j < 0:
                st[P_K] = k + 1
                st[P_PHASE] = _GROUP
                continue
            st[STRETCH] += stretches[j]
            st[P_T] = t + overhead + stretches[j]
            st[P_PHASE] = _PUSH
            if st[P_T] > st[NOW]:
                _schedule(st, q, st[P_T] - st[NOW], 1, _P)
                return 0
            continue
        if phase == _PUSH:
            count = leaving[j]
            if count and depth <= 0:
                st[ERR_A], st[ERR_B] = count, st[NOW]
                return 3
            st[P_WAITED], st[P_LEFT] = st[NOW], count
            st[P_PHASE] = _PUT
            continue
        if phase == _PUT:
            if st[P_LEFT]:
                chunk = min(st[P_LEFT], batch)
                st[P_CHUNK] = chunk
                st[P_PHASE] = _PUT_DONE
                if capacity - st[LEVEL] >= chunk:
                    st[LEVEL] += chunk
                    _schedule(st, q, 0, 1, _P)
                else:
                    st[PUT_WAITING] = chunk
                return 0
            st[BUS_STALL] += st[NOW] - st[P_WAITED]
            st[P_T] = st[NOW]
            st[P_PHASE] = _END
            continue
        if phase == _PUT_DONE:
            chunk = st[P_CHUNK]
            st[BUS_EVENTS] += 1
            st[PUSHED] += chunk
            st[MAX_OCC] = max(st[MAX_OCC], st[LEVEL])
            st[P_LEFT] -= chunk
            if not st[WORK_TRIGGERED]:
                st[WORK_TRIGGERED] = 1
                _schedule(st, q, 0, 1, _D_WORK)
            st[P_PHASE] = _PUT
            continue
        # _END: the slice is done
        if kg == ng - 1:
            pipe_ends[k // ng] = st[P_T]
        if k + 1 == ng * frames:
            st[EVENTS] += st[P_EVENTS]
            st[PIPE_END] = st[P_T]
            st[P_PHASE] = _FINISHED
            return 0
        st[P_K] = k + 1
        st[P_PHASE] = _GROUP


@numba.njit(cache=True, nogil=True)
def run_processes(
    st, q, groups, mores, frees, free_ptr, free_after, free_at, ready, issue_at, batches,
    loads, dims, pipe_ends,
):  # fmt: skip
    """Run the three processes until no event is left (:data:`DONE`), a flush is needed
    (:data:`NEED_FLUSH`: flush chunks ``st[N_FLUSHED] .. st[N_ISSUED] - 1`` into
    ``ready``, set ``st[N_FLUSHED]`` and call again) or an error (:data:`ERR_BUFFER`:
    slice ``st[ERR_A]``; :data:`ERR_PIXEL`: ``st[ERR_A]`` pixels at cycle ``st[ERR_B]``).

    ``groups`` int64 ``(ng, 4)`` one frame's beam groups ``(band, j, clocks, need)``;
    ``mores`` whether another group of its slice follows; ``frees``/``free_ptr`` (CSR
    over every frame's groups) the chunks each group frees; ``free_after``, ``free_at``
    over every frame's chunks (``free_at`` -1: not freed yet); ``loads`` rows ``stretch``
    and ``leaving`` per slice; ``dims`` ``(cap, ng, frames, nc, depth, capacity, batch,
    overhead)``; ``pipe_ends`` gets each frame's end.
    """
    cap, ng, frames, nc, batch = dims[0], dims[1], dims[2], dims[3], dims[6]
    total = nc * frames
    if not st[STARTED]:  # the processes' starts, in the order they were created
        st[STARTED] = 1
        st[P_PHASE] = _FINISHED if ng * frames == 0 else _GROUP
        _schedule(st, q, 0, 0, _D_START)
        _schedule(st, q, 0, 0, _M)
        _schedule(st, q, 0, 0, _P)
    while True:
        if st[P_ACTIVE]:
            code = _pipelines(
                st, q, groups, mores, frees, free_ptr, free_after, free_at, ready, loads, dims,
                pipe_ends,
            )  # fmt: skip
            if code != 0:
                return code
            st[P_ACTIVE] = 0
        kind = _pop(st, q)
        if kind < 0:
            return DONE
        if kind == _P:
            st[P_ACTIVE] = 1
        elif kind == _M:
            if not st[M_DONE]:
                _memory(st, q, free_at, issue_at, batches, cap, total, nc)
        elif kind == _D_START or kind == _D_WORK:
            _drain(st, q, batch)
        elif kind == _D_TIMEOUT:
            st[LEVEL] -= st[D_CHUNK]
            _schedule(st, q, 0, 1, _D_GET)
        else:  # _D_GET: the admission of a waiting put, then the bus goes on
            if st[PUT_WAITING] and dims[5] - st[LEVEL] >= st[PUT_WAITING]:
                st[LEVEL] += st[PUT_WAITING]
                st[PUT_WAITING] = 0
                _schedule(st, q, 0, 1, _P)
            st[BUS_EVENTS] += 2
            st[SENT] += st[D_CHUNK]
            st[BUS_END] = st[NOW]
            _drain(st, q, batch)


def simulate(model, chunks, groups, free_after, cap, busiest, beam_clocks, by_band, parked, *,
             frames):  # fmt: skip
    """:func:`pipeline_events.simulate
    <models.machines.volumepro.pipeline_events.simulate>` by
    :func:`run_processes` (one band, no slice FIFOs): the same statistics, pixel-bus
    totals and deferred reads."""
    from hwsim.engine.fifo import DeadlockError
    from models.machines.common.pixel_bus import PixelBus
    from models.machines.volumepro.chunk_reads import DeferredReads, chunk_streams
    from models.machines.volumepro.event_loop import EventLoop

    # The ports as pipeline_events builds them: one place for both paths (the tests that
    # put the transaction rung's SDRAM a clock off change it there).
    from models.machines.volumepro.pipeline_events import sdram_ports

    nc, ng, n_steps = len(chunks), len(groups), len(busiest)
    every = np.concatenate(
        [np.where(free_after >= 0, free_after + f * ng, -1) for f in range(frames)]
    ).astype(np.int64)
    env = EventLoop()  # the ports' clock: read_runs never reads it
    ports = sdram_ports(env, model)
    reads = DeferredReads(ports, chunk_streams(model, chunks), nc, frames)
    free_at = np.where(every < 0, 0, -1).astype(np.int64)  # no group needs it: free at 0
    freed = np.flatnonzero(every >= 0)
    frees = freed[np.argsort(every[freed], kind="stable")].astype(np.int64)
    free_ptr = np.zeros(ng * frames + 1, dtype=np.int64)
    np.cumsum(np.bincount(every[freed], minlength=ng * frames), out=free_ptr[1:])
    group_array = getattr(model, "_group_array", None)  # _schedule's, as an array
    if group_array is None or group_array.shape[0] != ng:
        group_array = np.array(groups, dtype=np.int64).reshape(-1, 4)
    mores = np.zeros(ng, dtype=np.bool_)
    if ng:
        # _slice_bounds' rule: the next group has the same (band, slice)
        mores[:-1] = np.all(group_array[1:, :2] == group_array[:-1, :2], axis=1)
    leaving = np.array(by_band[0], dtype=np.int64)
    if n_steps:
        leaving[n_steps - 1] += int(parked[0])
    stretches = np.maximum(np.asarray(busiest) - np.asarray(beam_clocks), 0).astype(np.int64)
    loads = np.stack([stretches, leaving]).reshape(2, n_steps)
    depth = int(model.pixel_fifo_depth)
    batch = max(1, min(int(model.row_pixels), -(-depth // 8)))
    overhead = int(model.arch.slice_overhead_cycles)
    dims = np.array([cap, ng, frames, nc, depth, max(depth, 1), batch, overhead], np.int64)
    ready = np.zeros(nc * frames, dtype=np.int64)
    issue_at = np.zeros(nc * frames, dtype=np.int64)
    batches = np.array(reads.streams.batches, dtype=np.int64).reshape(-1)
    if batches.size == 0:
        batches = np.zeros(1, dtype=np.int64)
    pipe_ends = np.zeros(frames, dtype=np.int64)
    st, q = new_state()
    args = (groups_or_empty(group_array), mores, frees, free_ptr, every, free_at, ready)
    while True:
        code = run_processes(st, q, *args, issue_at, batches, loads, dims, pipe_ends)
        _sync_issued(reads, issue_at, st)
        if code == NEED_FLUSH:
            n_issued, n_flushed = int(st[N_ISSUED]), int(st[N_FLUSHED])
            reads.flush(n_issued)
            ready[n_flushed:n_issued] = reads.ready[n_flushed:n_issued]
            st[N_FLUSHED] = n_issued
            continue
        if code == ERR_BUFFER:
            raise DeadlockError(
                f"input buffer: {model.capacity_mbbs} mini-block beams cannot "
                f"hold the sample window of slice {int(st[ERR_A])}"
            )
        if code == ERR_PIXEL:
            raise DeadlockError(
                f"pixel_bus.fifo: depth {depth} can never accept the {int(st[ERR_A])} pixels "
                f"pending at cycle {int(st[ERR_B])}; the compositors wait forever"
            )
        break
    reads.flush(reads.issued_count)  # bursts of chunks no group waited on
    finished = st[P_PHASE] == _FINISHED
    stats = {
        "events": int(st[EVENTS]),
        "stall": int(st[STALL]),
        "buffer_full": int(st[BUFFER_FULL]),
        "stretch": int(st[STRETCH]),
        "pipe_end": int(st[PIPE_END]),
        "section": 0,
        "pipe_ends": pipe_ends.tolist() if finished else [],
    }
    if stats["pipe_end"] == 0 and groups:
        raise DeadlockError("the pipelines never finished: the input buffer is too small")
    bus = PixelBus.totals(
        depth,
        row_pixels=model.row_pixels,
        pushed=int(st[PUSHED]),
        sent=int(st[SENT]),
        max_occupancy=int(st[MAX_OCC]),
        stall_cycles=int(st[BUS_STALL]),
        events=int(st[BUS_EVENTS]),
        end=int(st[BUS_END]),
    )
    return stats, bus, reads


def groups_or_empty(group_array: np.ndarray) -> np.ndarray:
    """``(ng, 4)`` groups, one dummy row when there are none (numba indexes no empty)."""
    return group_array if group_array.shape[0] else np.zeros((1, 4), dtype=np.int64)


def _sync_issued(reads, issue_at: np.ndarray, st: np.ndarray) -> None:
    """The chunks the loop issued since the last call, into ``reads.issue_at``."""
    have, n = len(reads.issue_at), int(st[N_ISSUED])
    if n > have:
        reads.issue_at.extend(issue_at[have:n].tolist())
