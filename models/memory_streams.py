"""Burst-request streams of a frame: which (bank, row, column) each memory module reads, in order.

# Ref: shared/docs/reference/architectures.md section 1.2-1.3 (Cube-4 skew, slice-by-slice
#      and beam-by-beam processing), section 3 (VolumePro 500 two-level mini-block skew,
#      US 6,266,733 [V abstract]; one mini-block = one burst of 8 [I]) and 9.5 item 2.

The renderer walks the volume slice by slice along the principal axis ``k`` and, inside a
slice, beam by beam along ``i`` (architectures.md 1.3 and 6.3: the permutation
``x -> (i, j, k) = (y, z, x)``, ``y -> (z, x, y)``, ``z -> (x, y, z)``).  The memory modules
work in parallel; each one receives, in that global order, the units that live in it.
These generators turn the layouts of :mod:`models.units.skew` into one ordered request
stream per module, ready for :func:`hwsim.memory.schedule_bursts` or
:class:`hwsim.memory.SdramEventModel`.

Layouts (``MemoryConfig.skew``):

``miniblock``
    VolumePro 500 (:func:`models.units.skew.vp500_miniblock`): 2x2x2 mini-blocks, module
    ``s mod M``, bank ``(s div M) mod K``; one mini-block is one burst of 8 words.  The
    walk goes over mini-block slabs (two voxel slices) and mini-block beams.
``block``
    The naive contrast: the same mini-blocks and module skew, but no bank skew.  Each
    module stores its mini-blocks linearly and the bank is the top address bits (a bank
    holds a quarter of the module's volume), the layout a controller gets without the
    second skew level.
``cube4``
    Cube-4 (:func:`models.units.skew.cube4_module` / ``cube4_address``): one voxel per
    module per clock, so one burst is one word (``burst_length`` 1 in the device).  Banks
    interleave rows: bank ``row_index mod K`` (the usual controller mapping).

Word address -> (bank, row, column): ``column = address mod columns``; the row index
``address div columns`` splits into bank and row as the layout says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.memory import BurstSchedule, MemoryConfig, schedule_bursts
from models.units import skew as sk

__all__ = ["AXES", "RequestStream", "module_streams", "processing_order", "schedule_frame"]

#: Principal axis -> (i, j, k) permutation of (x, y, z) indices (architectures.md 6.3).
AXES = {"x": (1, 2, 0), "y": (2, 0, 1), "z": (0, 1, 2)}


@dataclass(frozen=True)
class RequestStream:
    """One module's ordered burst requests (int64 arrays of equal length)."""

    bank: np.ndarray
    row: np.ndarray
    column: np.ndarray

    def __len__(self) -> int:
        return int(self.bank.size)


def processing_order(
    n: int, axis: str, reverse: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coordinates ``(x, y, z)`` of an ``n``-cube in processing order.

    Slice by slice along the principal ``axis`` (``"x"``, ``"y"`` or ``"z"``), beam by beam
    inside a slice, ``i`` fastest.  ``reverse`` walks the slices back to front.
    """
    if axis not in AXES:
        raise ValueError(f"axis must be one of {sorted(AXES)}, got {axis!r}")
    ii, jj, kk = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    # Order: k slowest, then j, then i.
    i = ii.transpose(2, 1, 0).ravel()
    j = jj.transpose(2, 1, 0).ravel()
    k = kk.transpose(2, 1, 0).ravel()
    if reverse:
        k = n - 1 - k
    xyz = [None, None, None]
    for role, coord in zip(AXES[axis], (i, j, k), strict=True):
        xyz[role] = coord.astype(np.int64)
    return xyz[0], xyz[1], xyz[2]


def _split(memory: MemoryConfig, module, bank, address) -> list[RequestStream]:
    dev = memory.sdram
    row, column = np.divmod(address, dev.columns)
    if row.size and row.max() >= dev.rows:
        raise ValueError(
            f"volume needs {int(row.max()) + 1} rows per bank, the device has {dev.rows}"
        )
    out = []
    for m in range(memory.modules):
        sel = module == m
        out.append(RequestStream(bank=bank[sel], row=row[sel], column=column[sel]))
    return out


def module_streams(
    memory: MemoryConfig, n: int, axis: str, reverse: bool = False, slabs: int | None = None
) -> list[RequestStream]:
    """Per-module burst streams of one frame of an ``n``-cube along ``axis``.

    Parameters
    ----------
    memory : MemoryConfig
        Module count, skew scheme and the device (its banks, columns, rows).
    n : int
        Voxels per axis (even for the mini-block layouts).
    axis : str
        Principal axis ``"x"``, ``"y"`` or ``"z"``.
    reverse : bool
        Walk the slices back to front.
    slabs : int, optional
        Only the first ``slabs`` slabs (mini-block layouts: pairs of slices; Cube-4: slices)
        of the walk, e.g. 1 for a single slice sweep of a large volume.

    Returns
    -------
    list of RequestStream
        One per module, in that module's issue order.
    """
    dev = memory.sdram
    M, K = memory.modules, dev.banks
    if memory.skew == "cube4":
        if dev.burst_length != 1:
            raise ValueError("the cube4 layout reads one voxel per burst: burst_length = 1")
        x, y, z = processing_order(n, axis, reverse)
        if slabs is not None:
            x, y, z = (v[: slabs * n * n] for v in (x, y, z))
        module = sk.cube4_module(x, y, z, M)
        address = sk.cube4_address(x, y, z, n, M)
        line = address // dev.columns
        bank = line % K
        return _split(memory, module, bank, (line // K) * dev.columns + address % dev.columns)
    if n % 2:
        raise ValueError("mini-block layouts need an even volume side")
    if dev.burst_length != 8:
        raise ValueError("mini-block layouts read one 2x2x2 mini-block per burst: burst_length 8")
    nb = n // 2
    bx, by, bz = processing_order(nb, axis, reverse)
    if slabs is not None:
        bx, by, bz = (v[: slabs * nb * nb] for v in (bx, by, bz))
    if memory.skew == "miniblock":
        module, bank, address = sk.vp500_miniblock(2 * bx, 2 * by, 2 * bz, n, M, K)
        return _split(memory, module, bank, address)
    if memory.skew == "block":
        module, bank, address = sk.block_miniblock(2 * bx, 2 * by, 2 * bz, n, M, K, dev.columns)
        return _split(memory, module, bank, address)
    raise ValueError(f"unknown skew {memory.skew!r}")


def schedule_frame(
    memory: MemoryConfig, n: int, axis: str, reverse: bool = False, slabs: int | None = None
) -> list[BurstSchedule]:
    """Cycle-exact schedules of every module for one frame read memory-bound (each
    request available at cycle 0); arguments as :func:`module_streams`.

    ``SdramStats.combine([s.stats for s in result])`` gives the frame's memory counters;
    its ``elapsed_cycles`` (memory clocks) is the frame's memory-bound time.
    """
    return [
        schedule_bursts(memory.sdram, s.bank, s.row)
        for s in module_streams(memory, n, axis, reverse, slabs)
    ]
