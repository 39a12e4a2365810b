"""The VolumePro-family volume memory: SDRAM modules holding 2x2x2 mini-blocks, read in bursts.

# Ref: architectures.md section 3 (US 6,266,733 two-level mini-block storage [V abstract]:
#      mini-blocks skewed across modules, then across banks; a de-skewing network reorders
#      the data; one mini-block = one burst of 8 [I]), section 2 (EM-Cube block skewing
#      [R med]) and 9.1 (voxel memory controller, de-skew network).

The host writes the volume once into ``[memory] modules`` SDRAM devices in the layout
``[memory] skew`` names (:mod:`models.units.skew`, the same formulas as
:mod:`models.memory_streams`):

``miniblock``
    mini-block ``(bx, by, bz)``, ``s = bx + by + bz``: module ``s mod M``, bank
    ``(s div M) mod K``, word address :func:`models.units.skew.vp500_miniblock`.
``block``
    the same module skew, mini-blocks stored linearly per module, the bank taken from the
    top address bits (no bank skew).

Volumes of any shape are stored in the layout of the enclosing even cube (side ``n``, the
largest side rounded up to even); the padding words are never read.  A slice is read as
the bursts of the mini-blocks it lies in; the de-skew network hands each pipeline the
Cube-4 slice stream (pipeline ``m`` receives voxel ``b = g P + ((m - q - a) mod P)`` of
beam ``a`` at clock ``a C + g``: :meth:`Cube4Memory.schedule`), which the ring links and
beam FIFO of :mod:`models.machines.common.slices` turn into cell corners.  Every slice read
checks the skew: each run of ``M`` consecutive mini-blocks along a beam must come from
``M`` distinct modules (``memory.conflicts``, which the tests require to be 0).
"""

from __future__ import annotations

import functools
import weakref

import numpy as np

from hwsim.core.errors import InputError
from hwsim.engine import Counters
from hwsim.memory import MemoryConfig
from models.machines.common.slices import SliceSchedule, slice_schedule
from models.units import skew as sk

__all__ = ["SdramVolume", "layout", "mini_block_bursts", "words_per_voxel"]


#: The SDRAM words of a volume (:meth:`SdramVolume._load`), by memory layout; dropped
#: with the volume.
_WORDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

#: Words kept with their volume for its later frames, at most (128 MiB: a 256^3 volume
#: of 32-bit voxels).  A 512^3 volume's 134 M words (0.27 GB) are written again for each
#: frame: kept, they sat beside the timing pass's arrays at the frame's memory peak.
KEEP_WORDS = 1 << 26


def words_per_voxel(volume, memory: MemoryConfig) -> int:
    """SDRAM words one voxel of ``volume`` occupies: two 16-bit words for a 32-bit voxel
    (VolumePro 1000's field containers, ``meta["container_bits"]``), else one."""
    bits = int(volume.meta.get("container_bits", 0)) or 1
    return max(1, -(-bits // memory.sdram.word_bits))


def mini_block_bursts(
    memory: MemoryConfig, module: np.ndarray, bank: np.ndarray, address: np.ndarray, words: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(module, bank, row)`` of every burst of the mini-blocks at word ``address`` (8
    words each in the one-word layout), ``words`` bursts per mini-block read back to back
    along the last axis: with 32-bit voxels a mini-block is two bursts of its 16 words,
    at word ``16 i`` and ``16 i + 8`` of the same row [I: the published sources give the
    voxel widths, not their SDRAM layout]."""
    if words == 1:
        return module, bank, address // memory.sdram.columns
    block = (address >> 3) * (8 * words)
    halves = block[..., None] + 8 * np.arange(words)
    rep = (*module.shape, words)
    out = np.broadcast_to(module[..., None], rep), np.broadcast_to(bank[..., None], rep)
    shape = (*module.shape[:-1], module.shape[-1] * words)
    return (
        out[0].reshape(shape),
        out[1].reshape(shape),
        (halves // memory.sdram.columns).reshape(shape),
    )


def layout(memory: MemoryConfig, n: int, x, y, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Module, bank and word address (inside the bank) of voxels ``(x, y, z)`` of an
    ``n``-cube (``n`` even) in ``memory``'s mini-block layout."""
    M, K = memory.modules, memory.sdram.banks
    if memory.skew == "miniblock":
        return sk.vp500_miniblock(x, y, z, n, M, K)
    if memory.skew == "block":
        return sk.block_miniblock(x, y, z, n, M, K, memory.sdram.columns)
    raise ValueError(f"the SDRAM front end reads mini-blocks: skew {memory.skew!r} unsupported")


class SdramVolume:
    """``M`` SDRAM modules holding one volume in mini-blocks.

    Parameters
    ----------
    raw : numpy.ndarray
        ``(z, y, x)`` raw voxels (at most 16 bits): an array, or anything with its
        ``shape``, ``dtype`` and z-planes ``raw[z]`` (read once each, in order:
        :func:`models.units.voxel.converted_planes`).
    memory : MemoryConfig
        Modules, skew and device (the arch's ``[memory]`` table).
    pipelines : int
        P: the de-skew network's output lanes.
    counters : Counters
    stuck_module : (int, int), optional
        Fault: module ``k`` returns ``value`` for every word.
    stuck_bank : (int, int, int), optional
        Fault: bank ``b`` of module ``k`` returns ``value`` for every word.
    source : str, optional
        The arch file, named when the volume does not fit the devices.
    kept_for : (Volume, int), optional
        The volume ``raw`` was converted from and the voxel width it was converted to:
        the written words are then kept with the volume for its later frames (up to
        :data:`KEEP_WORDS`).
    """

    def __init__(
        self,
        raw: np.ndarray,
        memory: MemoryConfig,
        pipelines: int,
        counters: Counters,
        *,
        stuck_module: tuple[int, int] | None = None,
        stuck_bank: tuple[int, int, int] | None = None,
        source: str | None = None,
        words_per_voxel: int = 1,
        kept_for: tuple[object, int] | None = None,
    ) -> None:
        self.shape = tuple(int(v) for v in raw.shape)
        self.words_per_voxel = int(words_per_voxel)
        self.memory, self.P, self.counters = memory, int(pipelines), counters
        self.M, self.K = memory.modules, memory.sdram.banks
        self.n = max(2, max(self.shape) + max(self.shape) % 2)
        self.stuck_module, self.stuck_bank = stuck_module, stuck_bank
        # The host's write depends on the voxels and the layout alone: kept per volume
        # (dropped with it, up to KEEP_WORDS), so a turntable's later frames do not write
        # it again.
        kept = _WORDS.setdefault(kept_for[0], {}) if kept_for is not None else {}
        key = (memory, self.n, raw.dtype.str, raw.shape, kept_for and kept_for[1])
        words = kept.get(key)
        if words is None:
            kept.clear()  # one layout per volume
            words = self._load(raw)
            if words.size <= KEEP_WORDS:
                kept[key] = words
        self.words: np.ndarray | None = words
        # The value words held here; the device holds every word of every voxel.
        stored = self.words.shape[2] * self.words_per_voxel
        rows = -(-stored // memory.sdram.columns)
        if rows > memory.sdram.rows:
            raise InputError(
                f"the volume needs {rows} SDRAM rows per bank, the device has {memory.sdram.rows}",
                source=source,
                key="memory.rows",
                allowed=f">= {rows} (or a smaller volume)",
            )
        counters.set("memory.words_per_bank", stored)
        self._schedules: dict = {}  # the de-skew network's output order (Cube-4's)
        self.reads = np.zeros(self.M, dtype=np.int64)

    def _load(self, raw: np.ndarray) -> np.ndarray:
        """The host's write: ``words[module, bank, address]``, one z-plane at a time.

        Each plane's addresses are computed, written and dropped (keeping them all was
        24 bytes a voxel).  The word array is sized up front from the last two planes'
        highest address (the top of the mini-block layout, whose addresses climb with
        ``z``): growing it by doubling held up to three times its 0.27 GB at 512^3 for a
        moment.  A layout whose top lies lower down (the block layout's banks wrap) grows
        it by doubling, then cuts it to the highest address written."""
        nz, ny, nx = self.shape
        y, x = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")

        def plane(z: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return layout(self.memory, self.n, x, y, np.full_like(x, z))

        first = max(int(plane(z)[2].max()) + 1 for z in {max(nz - 2, 0), nz - 1})
        words = np.zeros((self.M, self.K, first), dtype=np.uint16)
        size = 0
        for z in range(nz):
            m, b, a = plane(z)
            top = int(a.max()) + 1
            if top > words.shape[2]:
                grown = np.zeros((self.M, self.K, max(top, 2 * words.shape[2])), np.uint16)
                grown[:, :, : words.shape[2]] = words
                words = grown
            words[m.ravel(), b.ravel(), a.ravel()] = raw[z].ravel()
            size = max(size, top)
        return words if size == words.shape[2] else np.ascontiguousarray(words[:, :, :size])

    def release(self) -> None:
        """The frame reads no more voxels: its words are dropped (kept with the volume
        when small, :data:`KEEP_WORDS`), and the slices' read orders."""
        self.words = None
        self._schedules.clear()

    def schedule(self, kp: int, q: int) -> SliceSchedule:
        """Where each pipeline's voxel of slice ``q`` comes from, clock by clock."""
        return slice_schedule(self.shape, self.P, kp, q, self._schedules)

    def read_slice(self, kp: int, q: int) -> np.ndarray:
        """Voxel slice ``q`` along ``kp`` as the de-skewed ``(P, T)`` stream (0 in idle
        slots), read word by word from the modules that hold it; checks the skew."""
        sched = self.schedule(kp, q)
        z, y, x = sched.zyx
        module, bank, address = layout(self.memory, self.n, x, y, z)
        stream = self.words[module, bank, address].astype(np.int64)
        if self.stuck_module is not None:
            k, value = self.stuck_module
            stream[module == k] = value
        if self.stuck_bank is not None:
            k, b, value = self.stuck_bank
            stream[(module == k) & (bank == b)] = value
        stream[~sched.valid] = 0
        conflicts = self._conflicts(kp, q)
        self.counters.add("memory.conflicts", conflicts)
        if conflicts:
            raise AssertionError(f"skew violated: {conflicts} mini-block reads of slice {q}")
        self.reads += np.bincount(module[sched.valid], minlength=self.M)
        return stream

    def _conflicts(self, kp: int, q: int) -> int:
        """Runs of M consecutive mini-blocks along a beam of slice ``q`` that hit a module
        twice (0 for the mini-block and block layouts: ``s`` grows by one per mini-block)."""
        return _slice_conflicts(self.memory, self.n, self.shape, kp, q)

    def slab_bursts(self, kp: int, slab: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bursts of slab ``slab`` (voxel slices ``2 slab``, ``2 slab + 1`` along ``kp``):
        ``(module, bank, row)`` arrays ``(n_u, n_mb)`` of its mini-block beams ``u``
        (rows ``2u, 2u + 1`` of axis ``a``) and their bursts along the beam (one per
        mini-block; two with 32-bit voxels, :func:`mini_block_bursts`)."""
        axes = [ax for ax in range(3) if ax != kp]
        n_u = -(-self.shape[axes[0]] // 2)
        n_mb = -(-self.shape[axes[1]] // 2)
        coords = [None, None, None]
        coords[kp] = np.full((n_u, n_mb), 2 * slab)
        coords[axes[0]] = 2 * np.arange(n_u)[:, None] + 0 * coords[kp]
        coords[axes[1]] = 2 * np.arange(n_mb)[None, :] + 0 * coords[kp]
        module, bank, address = layout(self.memory, self.n, coords[2], coords[1], coords[0])
        return mini_block_bursts(self.memory, module, bank, address, self.words_per_voxel)

    def publish(self) -> None:
        """Per-module words delivered (2 bytes each; a 32-bit voxel is two)."""
        words = self.words_per_voxel * self.reads
        self.counters.add_lanes("memory.module[{}].words_read", words)
        self.counters.add_lanes("memory.module[{}].read_bytes", 2 * words)
        self.reads[:] = 0


@functools.lru_cache(maxsize=4096)
def _slice_conflicts(memory: MemoryConfig, n: int, shape: tuple, kp: int, q: int) -> int:
    """:meth:`SdramVolume._conflicts`: a property of the layout alone, so counted once per
    slice of a volume shape and memory (a turntable's frames read the same slices)."""
    axes = [ax for ax in range(3) if ax != kp]
    n_a, n_b = shape[axes[0]], shape[axes[1]]
    coords = [None, None, None]
    coords[kp] = np.full((n_a, -(-n_b // 2)), q)
    coords[axes[0]] = np.arange(n_a)[:, None] + 0 * coords[kp]
    coords[axes[1]] = 2 * np.arange(-(-n_b // 2))[None, :] + 0 * coords[kp]
    module = layout(memory, n, coords[2], coords[1], coords[0])[0]
    window = min(memory.modules, module.shape[1])
    return int(sum(np.count_nonzero(module[:, :-k] == module[:, k:]) for k in range(1, window)))
