"""Two threads for one VolumePro-family cycle frame: the steps' geometry ahead of the data
pass, the compiled stage's second pass behind it.

# Ref: models/machines/volumepro/cycle.py (``SlabMachine.run``, the data pass these
#      threads serve); hwsim/core/threads.py (``HWSIM_THREADS``, threads per frame).

With :func:`~hwsim.core.threads.frame_threads` above one, :meth:`SlabMachine.run
<models.machines.volumepro.cycle.SlabMachine.run>` hands work that reads no ray state to
two helper threads, and keeps on its own thread everything else, in the same order:

- :func:`steps_ahead`: each step's sample positions (``plan.steps()``), its voxel-slice
  window, its section's samples, their cells and lanes, and the section's book of them
  (:class:`SectionBook`: rays seen and finished, rule 8''s last slots, ring hand-offs;
  its marks and hand-offs one compiled loop that releases the GIL, :func:`_book_step`),
  computed up to :data:`STEPS_AHEAD` steps early (fewer for large images:
  :data:`RAYS_AHEAD`) on a worker thread (pure functions of the plan: the same arrays
  on any thread);
- :class:`FinishBehind`: the compiled stage's second pass
  (:meth:`SlabKernel.run <models.machines.volumepro.slab_kernel.SlabKernel.run>`'s
  gradients, shading and blend, a numba call that releases the GIL) on a worker thread
  while the data pass goes on to the next steps.  It writes only the accumulators of its
  step's rays, which nothing reads before :meth:`FinishBehind.join` (the pixel bus takes
  a section's finished rays and its partial rays are parked after the join); the passes
  run one at a time in step order, so every ray blends its samples in order.  A frame
  whose kernel also ends rays (early termination, ``alive``) or that takes the unit
  chain for a step (``SlabKernel.table`` is None) joins first, and a fault that clears
  accumulators on a hand-off (``dropped_handoff``) turns it off.

On a slice-FIFO machine a third helper plays the memory timing beside the data pass
(:mod:`models.machines.volumepro.timing_ahead`).

Slice loads, counters and the saturation log stay on the frame's thread, so images,
cycles and counters are the same bits for any thread count
(``tests/models/test_volumepro_threads.py``).
"""

from __future__ import annotations

import queue
import threading
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor

import numba
import numpy as np

from hwsim.golden.positions import Step
from models.backend import subset_step
from models.machines.volumepro.trilinear import TrilinearSource

__all__ = [
    "RAYS_AHEAD",
    "STEPS_AHEAD",
    "FinishBehind",
    "SectionBook",
    "finish_behind",
    "steps_ahead",
]

#: Steps whose geometry the worker may hold ready (each a few arrays of a step's size:
#: ~25 MB for a 512^2 image), and the rays they may hold in all (4 steps of a 256^2 image,
#: 1 of a 512^2: a large frame's memory peak stays near one thread's).
STEPS_AHEAD = 4
RAYS_AHEAD = 1 << 18
#: Second passes queued behind the data pass at most (each holds its step's planes).
FINISH_BEHIND = 2


def _geometry(machine, band: tuple[int, int], cut: bool, book: SectionBook) -> Iterator[tuple]:
    """Per step of the plan: ``(step, window, slots)``, ``step`` cut to the section rows
    ``band = [a0, a1)`` when ``cut``, ``slots = (source, a, b, lanes, fin, handoffs)``
    (None for an empty step): the trilinear source, each sample's slot and pipeline, and
    what ``book`` records of the step (:meth:`SectionBook.step`)."""
    m, (a0, a1) = machine, band
    for j, step in enumerate(m.plan.steps()):
        window = m.window(j)
        if cut and step.rays.size:
            rows = np.clip(np.floor(step.zyx[:, m.a_ax]), 0, m.n_a - 1)
            step = subset_step(step, (rows >= a0) & (rows < a1))
        slots = None
        if step.rays.size:
            source = TrilinearSource(m, step)
            slots = source, *book.step(j, step.rays, source)
        yield step, window, slots


def steps_ahead(
    machine, band: tuple[int, int], cut: bool, threads: int, book: SectionBook
) -> Iterator[tuple[Step, tuple[int, int], tuple | None]]:
    """:func:`_geometry`'s steps, on a worker thread up to :data:`STEPS_AHEAD` early (and
    :data:`RAYS_AHEAD` rays) when ``threads > 1``; in the caller's thread otherwise."""
    items = _geometry(machine, band, cut, book)
    if threads <= 1:
        return items
    return _ahead(items, max(1, min(STEPS_AHEAD, RAYS_AHEAD // max(machine.plan.n_rays, 1))))


class _Tally(list):
    """Counter increments made off the frame's thread, replayed on it in order."""

    def add(self, path: str, amount) -> None:
        self.append((path, int(amount)))

    def replay(self, counters) -> None:
        for path, amount in self:
            counters.add(path, amount)


class SectionBook:
    """What the data pass records of one section's steps that no ray state decides, kept
    by :func:`_geometry` (ahead, on its thread): the rays seen and finished (their last
    sample in this step, ``last_j``), each ray's record and slot of its last sample
    (``last_seen``, rule 8'; None: not kept) and the ring hand-offs (``prev_lane``: each
    ray's pipeline).  The frame reads ``seen`` and ``done`` once the section's steps are
    all taken; a hand-off that can clear accumulators (``dropped_handoff``) is made by the
    frame, in the step (:meth:`hand_off`)."""

    def __init__(self, machine, last_j, prev_lane, last_seen, first_record: int) -> None:
        n = last_j.size
        self.m, self.last_j, self.prev_lane, self.last_seen = machine, last_j, prev_lane, last_seen
        self.first_record = first_record
        self.seen, self.done = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        self.ahead = machine.faults.dropped_handoff is None

    def step(self, j: int, rays, source) -> tuple:
        """Step ``j``'s rays (samples of ``source``, a trilinear source) seen: their slots
        ``(a, b)`` (:meth:`SlabMachine._slots <models.machines.volumepro.cycle.SlabMachine.
        _slots>`) and lanes (the pipeline ``(q + a + b) % P`` of voxel slice ``q``), the
        record and slot of each, the rays the step finishes, and its hand-offs' counts
        (None: made by the frame).  Returns ``(a, b, lanes, fin, handoffs)``."""
        m, q = self.m, source.q
        if m.be.compiled:  # one compiled loop, the GIL released (_book_step)
            keep = self.last_seen is not None
            (ca, _, fa), (cb, _, fb) = source._cells
            a, b, lanes = (np.empty(rays.size, dtype=np.int64) for _ in range(3))
            fin, moved = _book_step(
                j,
                self.first_record + j,
                rays,
                (ca, fa, cb, fb, m.n_a, m.n_b),
                a,
                b,
                self.last_j,
                self.seen,
                self.done,
                self.last_seen if keep else _NO_SEEN,
                keep,
                q,
                self.m.P,
                lanes,
                self.prev_lane if self.ahead else _NO_LANES,
                self.ahead,
            )
            if not self.ahead:
                return a, b, lanes, fin, None
            tally = _Tally()
            tally.add("composite.handoffs", moved)
            return a, b, lanes, fin, tally
        a, b = m._slots(source)
        lanes = (q + a + b) % m.P
        self.seen[rays] = True
        if self.last_seen is not None:
            self.last_seen[0, rays] = self.first_record + j
            self.last_seen[1, rays], self.last_seen[2, rays] = a, b
        fin = rays[self.last_j[rays] == j]
        self.done[fin] = True
        if not self.ahead:
            return a, b, lanes, fin, None
        tally = _Tally()
        m._hand_off(rays, lanes, self.prev_lane, None, tally)
        return a, b, lanes, fin, tally

    def hand_off(self, handoffs: _Tally | None, rays, lanes, state) -> None:
        """The step's ring hand-offs on the frame's thread: counted, or made."""
        if handoffs is None:
            self.m._hand_off(rays, lanes, self.prev_lane, state)
        else:
            handoffs.replay(self.m.counters)


_NO_SEEN = np.zeros((3, 0), dtype=np.int64)
_NO_LANES = np.zeros(0, dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def _book_step(
    j, record, rays, cells, a, b, last_j, seen, done, last_seen, keep, q, P, lanes, prev_lane, hand
):
    """:meth:`SectionBook.step`'s marks in one loop over the step's rays (each at most
    once in a step, so the same arrays as its NumPy form): each sample's slot into ``a``
    and ``b`` (the nearest voxel to its cell ``cells = (ca, fa, cb, fb, n_a, n_b)``, as
    ``SlabMachine._slots``), its lane ``(q + a + b) % P`` into ``lanes`` (a mask when
    ``P`` is a power of two: the slots are not negative), ``seen``, rule 8''s record and
    slot (when ``keep``), the rays finished (``last_j == j``, in ``rays``' order), marked
    ``done``, and (when ``hand``) the ring hand-offs of
    :meth:`~models.machines.common.slice_order.SliceOrderMachine._hand_off` with no fault:
    each ray's pipeline ``prev_lane`` set to its lane, the moves counted.  Returns the
    rays finished and the moves."""
    ca, fa, cb, fb, n_a, n_b = cells
    mask = P - 1 if P & (P - 1) == 0 else -1
    fin = np.empty(rays.size, dtype=np.int64)
    n = 0
    moved = 0
    for i in range(rays.size):
        r = rays[i]
        a[i] = min(max(ca[i] + (1 if fa[i] >= 0.5 else 0), 0), n_a - 1)
        b[i] = min(max(cb[i] + (1 if fb[i] >= 0.5 else 0), 0), n_b - 1)
        slot = q + a[i] + b[i]
        lanes[i] = slot & mask if mask >= 0 else slot % P
        seen[r] = True
        if keep:
            last_seen[0, r] = record
            last_seen[1, r] = a[i]
            last_seen[2, r] = b[i]
        if last_j[r] == j:
            done[r] = True
            fin[n] = r
            n += 1
        if hand:
            before = prev_lane[r]
            if before >= 0 and before != lanes[i]:
                moved += 1
            prev_lane[r] = lanes[i]
    return fin[:n].copy(), moved


def _ahead(items: Iterator, depth: int) -> Iterator:
    """``items`` computed on a worker thread, up to ``depth`` ready; its exception is
    raised here, in order."""
    ready: queue.Queue = queue.Queue(depth)
    stop = threading.Event()

    def put(entry) -> bool:
        while not stop.is_set():
            try:
                ready.put(entry, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def work() -> None:
        try:
            for item in items:
                if not put((True, item)):
                    return
            put((False, None))
        except BaseException as exc:  # handed to the consumer, raised there
            put((None, exc))

    worker = threading.Thread(target=work, name="hwsim-steps", daemon=True)
    worker.start()
    try:
        while True:
            kind, item = ready.get()
            if kind is None:
                raise item
            if not kind:
                return
            yield item
    finally:
        stop.set()
        worker.join()


def finish_behind(machine, threads: int) -> FinishBehind:
    """The frame's :class:`FinishBehind`, installed on its kernel: active when ``threads >
    1``, the frame has a compiled stage whose passes end no rays (no early termination)
    and no fault clears accumulators on a hand-off."""
    kernel = machine.kernel
    active = (
        threads > 1
        and kernel is not None
        and kernel.ert_thr < 0
        and machine.faults.dropped_handoff is None
    )
    behind = FinishBehind(2 if active else 1)
    if kernel is not None:
        kernel.behind = behind
    return behind


class FinishBehind:
    """The compiled stage's second passes of one frame, run on a worker thread in step
    order (``threads > 1``) or at once; :meth:`join` waits for them and runs their
    ``after`` calls (checks and counts) on the frame's thread, in order."""

    def __init__(self, threads: int) -> None:
        self._pool = ThreadPoolExecutor(1, "hwsim-finish") if threads > 1 else None
        self._pending: deque[tuple[Future, Callable[[], None]]] = deque()

    @property
    def active(self) -> bool:
        """Whether passes may still be running when :meth:`launch` returns."""
        return self._pool is not None

    def launch(self, fn: Callable, args: tuple, after: Callable[[], None]) -> None:
        """Run ``fn(*args)`` (behind the data pass when active), then ``after()``."""
        if self._pool is None:
            fn(*args)
            after()
            return
        while len(self._pending) >= FINISH_BEHIND:
            self._settle()
        self._pending.append((self._pool.submit(fn, *args), after))

    def _settle(self) -> None:
        future, after = self._pending.popleft()
        future.result()
        after()

    def join(self) -> None:
        """Wait for every pass launched so far (their results and ``after`` calls)."""
        while self._pending:
            self._settle()

    def close(self) -> None:
        """End the worker thread (after :meth:`join`, or after an exception: the passes
        not yet joined are dropped, the running one finished first)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._pending.clear()
