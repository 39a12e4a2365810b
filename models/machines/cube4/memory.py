"""Cube-4's skewed volume memory: P modules, voxel (x, y, z) in module (x + y + z) mod P.

# Ref: architectures.md sections 1.2 (skew, conflict-free beams, in-module address [I])
#      and 1.3 (slice-by-slice, beam-by-beam order); models/units/skew.py (the formulas).

The host writes each voxel into the word ``cube4_address_zyx`` of module
``cube4_module``.  A frame reads the volume slice by slice along the principal axis
``kp`` and beam by beam inside a slice (beams run along the last in-slice axis ``b``).
Pipeline ``m`` reads only module ``m``: at cycle ``t = a C + g`` of a slice
(``C = ceil(n_b / P)`` cycles per beam) it receives the voxel
``b = g P + ((m - s - a) mod P)`` of beam ``a`` of slice ``s`` -- the beam arrives
cyclically rotated, which the ring links undo downstream.  Slots with ``b >= n_b``
(P not dividing the beam) are idle.  :meth:`Cube4Memory.account` checks, for every
read, that the module the schedule asks equals the module that holds the voxel and that
each module serves exactly one voxel per clock: the skew property as a counter
(``memory.conflicts``), which the tests require to be 0.
"""

from __future__ import annotations

import numpy as np

from hwsim.engine import Counters
from models.machines.common.slices import SliceSchedule, slice_schedule
from models.units.skew import cube4_address_zyx, cube4_module

__all__ = ["Cube4Memory", "WORD_BYTES", "slots_per_slice", "words_per_module"]

#: Bytes of one module word (a voxel of up to 16 bits).
WORD_BYTES = 2


def words_per_module(shape: tuple[int, int, int], P: int) -> int:
    """Words each of the ``P`` modules holds: every ``(z, y)`` row padded to whole groups
    of ``P`` voxels (:meth:`Cube4Memory.load`)."""
    nz, ny, nx = shape
    return max(nz * ny * -(-nx // P), 1)


def slots_per_slice(shape: tuple[int, int, int], P: int, kp: int) -> int:
    """Clocks a slice along ``kp`` takes to read: ``n_a ceil(n_b / P)``."""
    n_a, n_b = (shape[ax] for ax in range(3) if ax != kp)
    return n_a * -(-n_b // P)


class Cube4Memory:
    """P skewed memory modules holding one volume.

    Parameters
    ----------
    raw : numpy.ndarray
        ``(z, y, x)`` raw voxels (any integer dtype); copied into the modules.
    pipelines : int
        P, one module per pipeline.
    counters : Counters
    stuck_module : (int, int), optional
        Fault injection: module ``k`` returns ``value`` for every read.
    """

    def __init__(
        self,
        raw: np.ndarray | None,
        pipelines: int,
        counters: Counters,
        stuck_module: tuple[int, int] | None = None,
        *,
        shape: tuple[int, int, int] | None = None,
    ) -> None:
        self.shape = tuple(int(n) for n in (raw.shape if raw is not None else shape))
        self.P = P = int(pipelines)
        self.counters = counters
        self.stuck = stuck_module
        #: None: a memory that only counts its reads (a frame whose parts read their own
        #: voxels: :mod:`models.machines.cube4.bands`).
        self.modules = self.load(raw, P) if raw is not None else None
        counters.set("memory.words_per_module", words_per_module(self.shape, P))
        self._schedules: dict[tuple[int, int], tuple] = {}
        self._per_residue: dict[tuple[int, int], tuple[np.ndarray, int]] = {}
        self.reads = np.zeros(P, dtype=np.int64)
        self.idle_slots = np.zeros(P, dtype=np.int64)

    @staticmethod
    def load(raw: np.ndarray, P: int) -> np.ndarray:
        """The host's write of a volume: ``modules[m, a]`` holds the voxel whose
        :func:`cube4_module` is ``m`` and :func:`cube4_address_zyx` is ``a``.

        Row by row (a row is one ``(z, y)``, padded to ``nxp``): the row's words are
        ``row * nxp / P + x div P``, and module ``m`` takes ``x = g P + ((m - y - z) mod
        P)`` of group ``g`` -- the same map, gathered a module at a time instead of
        computing ``(x + y + z) mod P`` for every voxel.
        """
        nz, ny, nx = raw.shape
        rows, width = nz * ny, -(-nx // P)  # width: groups of P per padded row
        if nx == width * P and raw.dtype == np.uint16 and raw.flags.c_contiguous:
            padded = raw.reshape(rows, nx)  # a view: no copy of the volume
        else:
            padded = np.zeros((rows, width * P), dtype=np.uint16)  # voxels <= 16 bits
            padded[:, :nx] = raw.reshape(rows, nx)
        # Lane views of the rows; each module gathers only the rows it takes.
        by_lane = padded.reshape(rows, width, P).transpose(2, 0, 1)
        z, y = np.divmod(np.arange(rows), ny)
        residue = (y + z) % P
        modules = np.empty((P, words_per_module(raw.shape, P)), dtype=np.uint16)
        words = modules[:, : rows * width].reshape(P, rows, width)
        for r in range(P):
            sel = np.flatnonzero(residue == r)
            for m in range(P):
                words[m, sel] = by_lane[(m - r) % P].take(sel, axis=0)
        return modules

    def schedule(self, kp: int, s: int) -> SliceSchedule:
        """The read schedule of slice ``s`` along axis ``kp`` (cached per ``s mod P``)."""
        return slice_schedule(self.shape, self.P, kp, s, self._schedules)

    def account(self, kp: int, s: int) -> np.ndarray:
        """Count one read of slice ``s`` (every module's reads and idle slots, and the
        skew check: ``memory.conflicts``, reads whose scheduled module does not hold the
        voxel) and return the reads per module.

        What a read costs depends on ``s`` only through ``s mod P``: it is computed once
        per residue (from a schedule that is not kept, so P = 256 does not hold 256 of
        them) and counted on every read.
        """
        key = (kp, s % self.P)
        if key not in self._per_residue:
            sched = slice_schedule(self.shape, self.P, kp, s)
            z, y, x = sched.zyx
            holder = cube4_module(x, y, z, self.P)
            lane = np.arange(self.P)[:, None]
            conflicts = int(np.count_nonzero(sched.valid & (holder != lane)))
            self._per_residue[key] = (sched.valid.sum(axis=1), conflicts)
        reads, conflicts = self._per_residue[key]
        self.counters.add("memory.conflicts", conflicts)
        if conflicts:
            raise AssertionError(f"skew violated: {conflicts} reads of slice {s} hit a busy module")
        self.reads += reads
        self.idle_slots += slots_per_slice(self.shape, self.P, kp) - reads
        return reads

    def read_slice(self, kp: int, s: int) -> tuple[np.ndarray, SliceSchedule]:
        """Slice ``s`` as the modules deliver it: the ``(P, T)`` voxel stream (0 in idle
        slots) and its schedule.  Counted by :meth:`account`, not here."""
        sched = self.schedule(kp, s)
        z, y, x = sched.zyx
        lane = np.arange(self.P)[:, None]
        address = cube4_address_zyx(z, y, x, self.shape, self.P)
        stream = self.modules[lane, address].astype(np.int64)
        stream[~sched.valid] = 0
        if self.stuck is not None:
            k, value = self.stuck
            stream[k] = np.where(sched.valid[k], value, 0)
        return stream, sched

    def publish(self) -> None:
        """Write the per-module read and idle-slot counts into the counters."""
        self.counters.add_lanes("memory.module[{}].reads", self.reads)
        self.counters.add_lanes("memory.module[{}].idle_slots", self.idle_slots)
        # Modules hold 16-bit words (8- and 12-bit voxels are stored one per word).
        self.counters.add_lanes("memory.module[{}].read_bytes", self.reads * WORD_BYTES)
        self.reads[:] = 0
        self.idle_slots[:] = 0
