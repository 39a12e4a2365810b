"""The timing pass of a slice-FIFO VolumePro-family frame on a worker thread, played as
the data pass records its slices.

# Ref: models/machines/volumepro/timing.py (``timing_inputs``, the pass this plays early);
#      fifo_timing.py (rules 3', 5': ``fifo_work``); docs/cycle.md "Timing rules
#      (VolumePro family)".

On a slice-FIFO machine (VolumePro 500, EM-Cube: :func:`~models.machines.volumepro.
fifo_timing.uses_slice_fifos`, so no skipping and no early termination) the memory reads
every mini-block beam of a section, so the deliveries, each period's beams, the
deliveries they wait for and the beam that frees each (``free_after``) follow from the
geometry alone: the sections, each sample slice's window and its reach (rule 3').  Only
two things come from the data pass: a slice's samples per lane (``busy``: its stretch,
``extra``) and the rays parked at a section's end (the next section's ``pre``).

:class:`TimingAhead` (``threads > 1``, compiled, no waveform, no steady state) builds
each sample slice's window and reach, the deliveries and the periods on a worker thread
(``hwsim-timing``) at the frame's start with those two left out (the frame's thread only
fills the principal-axis taps first, one call), then plays each period through the memory loop
(:func:`~models.machines.volumepro.timing_kernel.play_once`, the GIL released per slice)
once the data pass has recorded its slice (:meth:`TimingAhead.record`, handed over
:data:`BATCH` at a time) and the parked rays before it (:meth:`TimingAhead.parked`).
Every period is completed before it is played, and they are played in order, so the
controllers, the pixel FIFO and the frame's timing are the serial pass's bits; a frame
whose loop needs more log room than the sizing guessed is played again from the start at
the join (:func:`~models.machines.volumepro.timing_kernel.play`).
"""

from __future__ import annotations

import queue
import threading

import numpy as np

from hwsim.engine import DrainFifo
from hwsim.memory import SdramController
from models.machines.volumepro.fifo_timing import DESKEW_WRITE, fifo_work, uses_slice_fifos
from models.machines.volumepro.fifo_timing import reach as fifo_reach
from models.machines.volumepro.slab_timing import (
    DeliveryTable,
    FrameTiming,
    run_timing,
    summarise_timing,
)
from models.machines.volumepro.timing import SliceRecord, deliveries_read

__all__ = ["TimingAhead", "timing_ahead"]

_END, _CANCEL = object(), object()
#: Slices handed to the thread at once.
BATCH = 16


def timing_ahead(m, sections, needed, threads: int, buffers: tuple):
    """The frame's :class:`TimingAhead`, started, or None when its timing stays at the
    frame's end: one thread, the unit chain, a waveform, the steady state, or a machine
    whose reads depend on samples (not :func:`uses_slice_fifos`)."""
    if (
        threads <= 1
        or not m.be.compiled
        or m.trace is not None
        or m.steady_state
        or not uses_slice_fifos(m.arch)
    ):
        return None
    return TimingAhead(m, sections, needed, buffers)


class TimingAhead:
    """One frame's timing pass on the ``hwsim-timing`` thread (see the module)."""

    def __init__(self, m, sections, needed, buffers: tuple[DrainFifo, int, int]) -> None:
        if m.plan.n_steps:  # the first window fills the taps of every step (``k_taps``)
            m.window(0)  # here: the threads then only read them
        self.m, self.buffers = m, buffers  # (pixel FIFO, buffer entries, capacity)
        self.pixel_fifo, self.capacity = buffers[0], buffers[2]
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._batch: list = []  # records and parked counts not yet handed over
        self._taken: list = []  # handed over, not yet taken by the thread
        self._result: tuple | None = None
        self.played = 0  # slices played so far (read by the tests)
        self._error: BaseException | None = None
        args = (sections, needed)
        self._thread = threading.Thread(
            target=self._work, args=args, name="hwsim-timing", daemon=True
        )
        self._thread.start()

    # ---------------------------------------------------------------- frame thread

    def record(self, rec: SliceRecord) -> None:
        """A sample slice recorded (final: the frame changes only its ``arrivals``,
        which the slice-FIFO periods do not read); handed over :data:`BATCH` at a time
        (a wake-up of the thread per slice would cost GIL hand-offs)."""
        self._batch.append(rec)
        if len(self._batch) >= BATCH:
            self._flush()

    def parked(self, count: int) -> None:
        """The rays parked at the end of the section whose slices were recorded."""
        self._batch.append(count)
        self._flush()

    def _flush(self) -> None:
        if self._batch:
            self._inbox.put(self._batch)
            self._batch = []

    def join(self) -> tuple[DeliveryTable, list, object, FrameTiming]:
        """Wait for the pass (every slice recorded): ``(deliveries, slices, plan,
        timing)`` as ``timing_inputs`` and ``run_timing`` give them; its error raised
        here."""
        self._flush()
        self._inbox.put(_END)
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._result

    def close(self) -> None:
        """End the thread early (the data pass failed)."""
        if self._thread.is_alive():
            self._inbox.put(_CANCEL)
            self._thread.join()

    # ---------------------------------------------------------------- worker thread

    def _work(self, sections, needed) -> None:
        try:
            m = self.m  # each slice's window and reach (rule 3'): read from the taps
            windows = [m.window(j) for j in range(m.plan.n_steps)]
            reaches = [fifo_reach(m, j) for j in range(m.plan.n_steps)]
            self._result = self._play(sections, needed, windows, reaches)
        except _Cancelled:
            pass
        except BaseException as exc:  # raised on the frame's thread at the join
            self._error = exc

    def _play(self, sections, needed, windows, reaches):
        m, P = self.m, self.m.P
        banks, rows, starts, index = deliveries_read(m, sections, needed)
        idle = np.zeros(P, dtype=np.int64)
        skeleton = [
            SliceRecord(si, windows[j], None, idle, 0, reaches[j])
            for si in range(len(sections))
            for j in range(len(windows))
        ]
        # The periods with no stretch and no parked rays: completed as the slices come.
        slices, free_after, plan = fifo_work(
            m, skeleton, sections, [0] * len(sections), index, starts.shape[1] - 1
        )
        table = DeliveryTable(banks, rows, starts, free_after)
        sdram = m.memory_cfg.sdram
        timing = _fresh(slices, table)
        room = _room(table, slices, sdram, m.memory_cfg.modules)
        controllers = [SdramController(sdram) for _ in range(m.memory_cfg.modules)]
        fifo = dict(vars(self.pixel_fifo))
        from models.machines.volumepro.timing_kernel import play_once  # imports numba

        completed = self._completed(slices, plan.period, len(windows))
        done = play_once(
            table, completed, controllers, room,
            capacity=self.capacity, pixel_fifo=self.pixel_fifo, out=timing[0],
            ends=timing[1], ready=timing[2], tail=sdram.cas_latency + sdram.burst_cycles,
            ratio=sdram.clock_ratio, deskew=DESKEW_WRITE,
        )  # fmt: skip
        if not done:  # more room than guessed: the serial pass, from the start
            for _ in completed:  # every slice completed first
                pass
            vars(self.pixel_fifo).update(fifo)
            out = run_timing(
                m.memory_cfg, table, slices, capacity=self.capacity,
                pixel_fifo=self.pixel_fifo, counters=m.counters, keep_bursts=False,
                deskew=DESKEW_WRITE,
            )  # fmt: skip
            return table, slices, plan, out
        table.banks = table.rows = None  # read no more (run_timing's keep_bursts=False)
        n_beams = sum(int(s.needs.size) for s in slices)
        out = summarise_timing(timing[0], controllers, timing[1][:n_beams], slices, False)
        return table, slices, plan, out

    def _completed(self, slices, period, n_steps: int):
        """``slices`` in order, each once the data pass has given what completes it: its
        record's ``busy`` (and stretch) and, first in a section, the rays parked before."""
        C = self.m.C
        parked: list[int] = []
        k = 0
        for r, p in enumerate(period.tolist()):
            rec = self._take(parked)
            first = k if r % n_steps == 0 and r else -1  # a section's first period
            while k <= p:
                work = slices[k]
                if k == first:  # fifo_work's ``pre`` with this section's parked rays
                    work.pre += parked[rec.section - 1]
                if k == p:  # fifo_work's stretch, from the slice's samples per lane
                    stretch = max(0, int(rec.busy.max(initial=0)) - work.needs.size * C)
                    work.extra += stretch
                    work.busy = rec.busy
                yield work
                self.played = k = k + 1
        yield from slices[k:]

    def _take(self, parked: list[int]) -> SliceRecord:
        """The next record, parked counts taken on the way into ``parked``."""
        while True:
            if not self._taken:
                batch = self._inbox.get()
                self._taken = batch[::-1] if isinstance(batch, list) else [batch]
            got = self._taken.pop()
            if got is _CANCEL:
                raise _Cancelled
            if got is _END:
                raise RuntimeError("the data pass recorded fewer slices than its plan")
            if isinstance(got, SliceRecord):
                return got
            parked.append(got)


class _Cancelled(Exception):
    """The frame ended the pass early."""


def _fresh(slices, table) -> tuple[FrameTiming, np.ndarray, np.ndarray]:
    """``run_timing``'s ``out``, ``ends`` and ``ready`` before the loop."""
    n_beams = sum(int(s.needs.size) for s in slices)
    ends = np.zeros(max(n_beams, 1), dtype=np.int64)
    return FrameTiming(), ends, np.zeros(max(len(table), 1), dtype=np.int64)


def _room(table, slices, sdram, modules: int) -> tuple[int, int]:
    """Log room for the loop: :func:`~models.machines.volumepro.timing_kernel.first_room`
    on the periods before their stretch and parked rays, with the refreshes doubled (a
    frame that needs more is played again at the join)."""
    from models.machines.volumepro.timing_kernel import first_room

    booked, refreshes = first_room(table, slices, sdram, sdram.clock_ratio)
    return booked, 2 * refreshes
