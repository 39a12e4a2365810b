"""A Cube-4 frame split by bands of rays, each band on its own worker, combined exactly.

# Ref: architectures.md sections 1.1-1.3 (slice-parallel order, skewed memory, only
#      local neighbour links); issue 20 (a 1024^3 frame split across Dask workers).

Cube-4's datapath is local: a sample reads the voxels of its own cell, the cells one
voxel away and the same cell on the slices ahead and behind, and a band of a slice's
beams routed through the ring links and beam FIFOs on its own delivers every corner of a
cell whose beams lie in the band exactly as the whole slice does
(``tests/arch/test_slice_datapath_locality.py``).  So a frame splits as the rays do:

1. :func:`split_rays` cuts the plan's rays into bands along the beam axis ``a`` (by the
   ray's position at its middle sample; equal samples per band);
2. :func:`sweep_band` (on a worker) reads, for every slice, only the beams its rays'
   cells need -- plus the halo the datapath reads around them, proved in
   :func:`_band_origins` (one cell below, one above, and above that what a shortened
   beam FIFO reaches), for the steps that read the slice -- from a
   :class:`~hwsim.volumes.parts.VolumeParts`
   (never the whole volume), builds their skewed stream by the memory's schedule, routes
   it through a band-sized :class:`SliceDatapath` and runs
   :meth:`Cube4Machine.sample_pass` over its rays only;
3. :meth:`Cube4Machine.frame` (in the driver) adds the bands' samples per pipeline and
   step, and times the frame by its rules: every slice read once, each slice as long as
   its busiest pipeline, the pixel bus from the whole plan.  Nothing of a part's timing
   is summed: the timing is the frame's.

What cannot be split exactly is refused (:func:`check_splittable`): a slice FIFO of
another depth than a slice (it moves data across slices), a beam FIFO deeper than a beam
(it reaches into the beam before a band), a waveform (its clocks are the whole frame's).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable

import numpy as np

from hwsim.core.cluster import peak_rss_bytes, reset_peak_rss
from hwsim.core.errors import InputError
from hwsim.engine import Counters
from hwsim.golden.positions import SamplePlan
from hwsim.volumes.parts import VolumeParts
from models.backend import Backend
from models.frame import Frame
from models.machines.common.slices import SliceDatapath, SlicePath
from models.machines.cube4.cycle import Cube4Machine, Faults, Sweep
from models.units.voxel import convert_values

__all__ = [
    "BandSplit",
    "BandSlices",
    "band_stream",
    "check_splittable",
    "split_rays",
    "sweep_band",
    "BandReport",
    "beam_fifo_reach",
]

#: Cells of halo below and above a band's sample cells: the gradient's neighbours one
#: voxel away.  One is enough and needed (the proof: :func:`_band_origins`); a shortened
#: beam FIFO adds :func:`beam_fifo_reach` above.
HALO_CELLS = 1


def check_splittable(faults: Faults | None, *, trace: bool = False) -> None:
    """Refuse, with one line, what a frame split by bands cannot reproduce exactly."""
    faults = faults or Faults()
    if faults.slice_fifo_adjust:
        raise InputError(
            "a slice FIFO of another depth than a slice moves voxels across slices: "
            "its frame cannot be split by bands",
            key="faults.slice_fifo_adjust",
            allowed="0 (or render it in one process)",
        )
    if faults.beam_fifo_adjust > 0:
        raise InputError(
            "a beam FIFO deeper than a beam reaches into the beam before a band: "
            "its frame cannot be split by bands",
            key="faults.beam_fifo_adjust",
            allowed="<= 0 (or render it in one process)",
        )
    if trace:
        raise InputError(
            "a waveform's clocks are the whole frame's: it is written in one process",
            key="--trace",
            allowed="no --workers",
        )


def split_rays(plan: SamplePlan, parts: int, a_ax: int) -> list[np.ndarray]:
    """The plan's rays (indices into its per-ray arrays, ascending) in ``parts`` bands
    along the beam axis ``a_ax``: rays ordered by their position along it at their middle
    sample, cut where the running sample count crosses each ``k / parts`` of the frame's.
    Bands never share a ray; a band may be empty when there are fewer rays than parts."""
    n = plan.ray_ids.size
    if n == 0:
        return [np.zeros(0, dtype=np.int64) for _ in range(parts)]
    mid = (plan.j_lo + plan.j_hi) // 2
    key = plan.position(mid, np.arange(n))[:, a_ax]
    order = np.argsort(key, kind="stable")
    weight = (plan.j_hi - plan.j_lo + 1)[order]
    cum = np.cumsum(weight)
    cuts = np.searchsorted(cum, cum[-1] * np.arange(1, parts) / parts, side="left")
    return [np.sort(band) for band in np.split(order, cuts)]


def band_stream(rows: np.ndarray, q: int, a0: int, P: int) -> tuple[np.ndarray, np.ndarray]:
    """The memory's ``(P, H C)`` stream of beams ``a0 .. a0 + H - 1`` of slice ``q``
    (``rows``: their raw voxels, ``(H, n_b)``) and its valid slots: pipeline ``(q + a +
    b) mod P`` receives voxel ``(a, b)`` at slot ``(a - a0) C + b div P`` (the skew
    schedule, architectures.md 1.2), 0 in idle slots."""
    H, n_b = rows.shape
    C = -(-n_b // P)
    a = np.arange(a0, a0 + H)[:, None]
    b = np.arange(n_b)[None, :]
    lane = (q + a + b) % P
    slot = (a - a0) * C + b // P
    stream = np.zeros((P, H * C), dtype=np.int64)
    valid = np.zeros((P, H * C), dtype=bool)
    stream[lane, slot] = rows
    valid[lane, slot] = True
    return stream, valid


class BandSlices:
    """The corner planes a band's steps read: for every slice, the beams
    ``a0[q] .. a0[q] + H - 1`` read from ``parts`` (the volume, a box at a time) and routed
    through a band-sized datapath, kept while a step needs them."""

    def __init__(self, m: Cube4Machine, parts: VolumeParts) -> None:
        self.m, self.parts = m, parts
        self.a0, self.H = _band_origins(m)
        path = SlicePath(
            pipelines=m.P,
            beam_fifo_adjust=m.faults.beam_fifo_adjust,
            dropped_link=m.faults.dropped_link,
        )
        self.datapath = SliceDatapath(path, (max(self.H, 1), m.n_b), Counters())
        self._cache: dict[int, dict] = {}
        self.rows_read = 0

    def prime(self) -> None:
        """Nothing to prime: each slice is read when a step first needs it."""

    def _rows(self, q: int, a0: int) -> np.ndarray:
        """Raw voxels of beams ``a0 .. a0 + H - 1`` of slice ``q``, ``(H, n_b)``."""
        m, H = self.m, self.H
        band, here = slice(a0, a0 + H), slice(q, q + 1)
        if m.kp == 0:  # a = y, b = x
            values = self.parts.box(here, band)[0]
        elif m.kp == 1:  # a = z, b = x
            values = self.parts.box(band, here)[:, 0, :]
        else:  # a = z, b = y
            values = self.parts.box(band, slice(None), q)
        self.rows_read += H
        return convert_values(values, m.be.volume, m.dp.voxel_bits)[0]

    def _planes(self, q: int) -> dict:
        m, a0 = self.m, int(self.a0[q])
        stream, valid = band_stream(self._rows(q, a0), q, a0, m.P)
        stuck = m.faults.stuck_module
        if stuck is not None:
            k, value = stuck
            stream[k] = np.where(valid[k], value, 0)
        return m.corner_planes(stream, q, self.datapath, a0)

    def at(self, j: int) -> dict[int, dict]:
        m = self.m
        q = m.slice_of(j)
        reach = 1 if m.need_slices else 0
        wanted = [k for k in range(q - reach, q + reach + 1) if 0 <= k < m.n_kp and self.a0[k] >= 0]
        for old in [k for k in self._cache if k not in wanted]:
            del self._cache[old]
        for k in wanted:
            if k not in self._cache:
                self._cache[k] = self._planes(k)
        return {k: self._cache[k] for k in wanted}


def beam_fifo_reach(C: int, adjust: int) -> int:
    """Beams past a cell's own that its corner ``(a, b)`` is read from through a beam FIFO
    ``adjust <= 0`` entries off its depth ``C + 1``: the FIFO of depth ``C + 1 + adjust``
    hands cell ``(a, b)`` the stream slot ``a C + b div P - adjust``, which for the beam's
    last group (``b div P = C - 1``) lies ``(C - 1 - adjust) div C`` beams on: 0 for the
    machine's FIFO, 1 for ``-C <= adjust <= -1``, 2 for a FIFO of depth 0.  (Deeper FIFOs
    reach back into the beam before; :func:`check_splittable` refuses them.)"""
    return (C - 1 - adjust) // C


def _band_origins(m: Cube4Machine) -> tuple[np.ndarray, int]:
    """Per slice, the first beam ``a0`` of the band its steps read (-1: no step reads
    it), and the band's height ``H`` (the same for every slice, so one datapath serves).

    A slice ``q`` is read by its own step and, with gradients (``m.need_slices``), by the
    steps before and after it; ``first``/``last`` are the least and greatest sample cell
    ``floor(p_a)`` along the beam axis over the band's samples of those steps.  The band
    reads beams ``first - HALO_CELLS .. last + 1 + HALO_CELLS + r`` (``r``:
    :func:`beam_fifo_reach`), clipped to the slice.  That is exactly what the datapath
    reads, with ``HALO_CELLS = 1``:

    1. *Which cells a sample reads.*  A sample at ``p`` (``p_a``, float64; ``c =
       floor(p_a)``) reads its own cell ``c`` on its slice and, for its gradient, the
       same cell (same weight) on the slices ahead and behind, and on its slice the cells
       of ``fl(p_a - 1.0)`` and ``fl(p_a + 1.0)`` (rounded as float64, each weight
       quantised from its own fraction; ``HardwareSource.gradient``, the slice kernel).
       Neighbours along ``b`` change no beam: a band holds whole beams.  Rounding to
       nearest is monotone and leaves the integers ``c - 1`` and ``c + 2`` where they are,
       and ``c - 1 <= p_a - 1 < c``, ``c + 1 <= p_a + 1 < c + 2``; so the down neighbour's
       cell is ``c - 1`` or ``c``, and the up neighbour's ``c + 1``, or ``c + 2`` exactly
       when ``p_a + 1`` rounds up onto the integer ``c + 2``: then its fraction, and its
       weight, is 0.  That happens where ``p_a`` is the last float below a power of two
       or lies in ``[-2^-54, 0)``, and views make it: a beam-axis shear that is
       trigonometric noise (azimuth 270, along -x: ``cos(270 deg) = -1.8e-16``) puts
       whole rows of samples at ``16 - 2^-49``, ``8 - 2^-50``, ...
    2. *Which beams a cell's corners come from.*  Cell ``c``'s corner ``(c, b)`` arrives
       through the beam FIFO from beams ``c .. c + r``; ``(c, b + 1)`` over the ring from
       beam ``c`` (in the far column it is ``(c, b)``'s replica: ``c .. c + r``); ``(c +
       1, b)`` and ``(c + 1, b + 1)`` one beam later, from beam ``c + 1``
       (``models/machines/common/slices.py``; ``tests/arch/
       test_slice_datapath_locality.py`` checks each corner's reach, and that it is no
       shorter).  A lerp with weight 0 returns its first operand exactly, in every
       rounding mode: a cell read with weight 0 along ``a`` uses only its corners on beam
       ``c``'s side (beams ``c .. c + r``); otherwise beams ``c .. c + max(1, r)``.  (A
       sample's own cell is read whole either way: the transparent-cell shortcut looks at
       its four corners.)
    3. *So a step whose sample cells span* ``[f, l]`` reads beams ``f - 1 ..`` (the down
       neighbour ``c - 1``) ``.. max(l + 1 + max(1, r), l + 2 + r) = l + 2 + r`` on its
       slice (the up neighbour, ``c + 1`` with any weight or ``c + 2`` with weight 0), and
       ``f .. l + max(1, r)`` on the slices ahead and behind: inside ``first - 1 .. last +
       2 + r``.  Outside the slice, cells below 0 replicate beam 0 and beams past the last
       read the flush's zeros, in a band starting at beam 0 or ending at the last beam as
       in the whole slice (the clip, and ``a0 = min(bottom, n_a - H)`` keeps a band that
       needs the last beam ending there).  A band of beams ``a0 .. e`` delivers exactly
       what the whole slice delivers for every corner whose beams lie in it (the locality
       test), and ``H`` is the tallest slice's height, so every slice's band holds its
       beams.
    4. *Neither bound is loose.*  Below: a view along an axis puts samples on integers,
       ``p_a - 1`` is the integer ``c - 1``, and the down neighbour, cell ``c - 1`` at
       fraction 0, reads beam ``c - 1`` alone (``HALO_CELLS = 0`` changes the image at
       every band count:
       ``test_split_frame.py::test_the_halo_below_a_band_is_read_at_every_band_count``).
       Above: an up neighbour ``c + 1`` with a non-zero weight reads beam ``c + 2`` (one
       above, without the reach, fails the x-principal and stuck-module frames of
       ``test_a_frame_split_into_bands_is_the_one_process_frame``); through a shortened
       FIFO an up neighbour ``c + 2`` at weight 0 reads beam ``c + 2 + r`` in a beam's
       last group (``test_a_shortened_beam_fifo_reads_past_the_halo``: without the reach
       the image differs, and for a FIFO of depth 0 so it did with the fixed halo of 2
       this replaced).  ``test_every_cell_a_band_reads_lies_in_its_rows`` checks every
       read against the band's rows over a sweep of views, shapes, P, faults and cuts.

    Nothing else widens it: rays are assigned to bands by their middle sample, but
    ``first``/``last`` are taken over every sample of every step, so a ray that drifts
    across beams (oblique and perspective views) widens the band, not the halo; the
    gradient's neighbours are one index unit away whatever the voxel spacing; Cube-4
    takes one sample per slice (supersampling is refused); the band's height being the
    tallest slice's only adds beams.
    """
    plan, n_a = m.plan, m.n_a
    lo = np.full(plan.n_steps, np.iinfo(np.int64).max, dtype=np.int64)
    hi = np.full(plan.n_steps, np.iinfo(np.int64).min, dtype=np.int64)
    for j, step in enumerate(plan.steps()):
        if step.rays.size:
            cells = np.floor(step.zyx[:, m.a_ax])
            lo[j], hi[j] = int(cells.min()), int(cells.max())
    reach = 1 if m.need_slices else 0
    steps_of = np.array([m.slice_of(j) for j in range(plan.n_steps)], dtype=np.int64)
    first = np.full(m.n_kp, np.iinfo(np.int64).max, dtype=np.int64)
    last = np.full(m.n_kp, np.iinfo(np.int64).min, dtype=np.int64)
    for shift in range(-reach, reach + 1):
        q = steps_of + shift
        ok = (q >= 0) & (q < m.n_kp)
        np.minimum.at(first, q[ok], lo[ok])
        np.maximum.at(last, q[ok], hi[ok])
    used = first <= last
    above = HALO_CELLS + beam_fifo_reach(m.C, m.faults.beam_fifo_adjust)
    bottom = np.clip(first - HALO_CELLS, 0, n_a - 1)
    top = np.clip(last + 1 + above, 0, n_a - 1)
    H = int((top - bottom + 1)[used].max(initial=0))
    a0 = np.where(used, np.minimum(bottom, n_a - H), -1)
    return a0, H


@dataclasses.dataclass
class BandReport:
    """What a band's worker measured: its rays and samples, the beams it read per slice,
    its wall time and its process's peak resident memory over the band."""

    band: int
    rays: int
    samples: int
    rows: int
    seconds: float
    peak_rss_bytes: int
    host: str


def sweep_band(
    frame: Frame,
    parts: VolumeParts,
    rays: np.ndarray,
    band: int,
    *,
    faults: Faults | None = None,
    compiled: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Sweep, BandReport]:
    """Run the plan rays ``rays`` of ``frame`` (a :func:`split_rays` band) through the
    machine, reading only their rows of the volume from ``parts``: a worker's task."""
    start = time.perf_counter()
    reset_peak_rss()
    plan = frame.plan.subset(np.isin(np.arange(frame.plan.ray_ids.size), rays))
    backend = Backend(dataclasses.replace(frame, plan=plan), compiled=compiled)
    machine = Cube4Machine(backend, faults=faults)
    if plan.ray_ids.size:
        slices = BandSlices(machine, parts)
        sweep = machine.sample_pass(slices, progress)
        rows = slices.rows_read
    else:  # nothing to do; every pipeline idle in this band
        sweep = Sweep(
            rays=plan.ray_ids,
            acc=backend.new_state(0).acc,
            touched=np.zeros(0, dtype=bool),
            dt_sum=backend.new_state(0).dt_sum,
            busy=np.zeros((plan.n_steps, machine.P), dtype=np.int64),
            samples=0,
            skipped=0,
            counters={},
        )
        rows = 0
    report = BandReport(
        band=band,
        rays=int(plan.ray_ids.size),
        samples=int(sweep.samples),
        rows=int(rows),
        seconds=time.perf_counter() - start,
        peak_rss_bytes=peak_rss_bytes(),
        host=f"{os.uname().nodename}:{os.getpid()}",
    )
    return sweep, report


class BandSplit:
    """A Cube-4 frame split by bands of rays (the family's ``Machine.split``): the driver
    builds one, cuts the rays with :meth:`bands`, runs :attr:`task` once per band (on a
    worker, each with the volume's :class:`VolumeParts`) and hands the results to
    :meth:`combine`."""

    #: ``task(frame, parts, rays, band, *, faults, progress)``: one band on a worker.
    task = staticmethod(sweep_band)

    def __init__(self, frame: Frame, faults: Faults | None = None, *, trace: bool = False) -> None:
        check_splittable(faults, trace=trace)
        self.frame, self.faults = frame, faults
        self.machine = Cube4Machine(Backend(frame), faults=faults)

    def bands(self, n: int) -> list[np.ndarray]:
        return split_rays(self.frame.plan, n, self.machine.a_ax)

    def combine(self, sweeps: list[Sweep]):
        """The frame's :class:`~models.machines.common.results.CycleResult`."""
        return self.machine.frame(sweeps)
