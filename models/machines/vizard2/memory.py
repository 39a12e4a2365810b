"""VIZARD II volume memory and VoxelCache: block-linear SDRAM image, direct-mapped block cache.

# Ref: architectures.md section 5 (VIZARD II: volume in DIMMs, up to 1 GB [V]; table of
#      pre-computed gradients [V]; ray queueing to cut SDRAM page misses, Doggett ISCAS
#      2000 [V]; VoxelCache: on-chip cache of 4^3-voxel blocks, Kanus et al. GH 2003 [V])
#      and 9.1 (SDRAM controller); the layout and cache organisation are [I].

**Memory image** (written once by the host).  The volume is cut into 4^3-voxel blocks,
stored block after block (block ``b = (bz nby + by) nbx + bx``), voxel ``((z & 3) 4 +
(y & 3)) 4 + (x & 3)`` inside a block.  Two regions on one 64-bit DIMM channel: the voxel
values (16 bits each: a block is 16 words, 2 bursts of 8) and the gradient table (the
pre-computed central differences ``[dx, dy, dz]`` of every voxel, ``gradient_bits`` each:
a block is ``3 gradient_bits`` words).  A word address maps to page ``addr div columns``,
bank ``page mod banks``, row ``page div banks``: consecutive blocks along x share a page.

**VoxelCache** (:class:`BlockCache`).  Direct-mapped: block ``(bz, by, bx)`` lives in
line ``((bz mod Sz) Sy + by mod Sy) Sx + bx mod Sx`` with ``(Sz, Sy, Sx)`` the
``[buffers] cache_sets`` (each >= 2, so the up to 8 blocks a sample's 8 voxels touch
always sit in different lines).  Lookups happen in issue order; a miss fills the whole
line (values, and gradients when the scene uses them) from the memory image.  Hit or miss
depends only on the order of lookups, so one step's lookups are resolved at once (sorted
by line); the cycles they cost come from the SDRAM model in :mod:`models.machines.vizard2.cycle`.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.memory import MemoryConfig
from models.machines.vizard2.config import BLOCK
from models.units import gradient as gradient_unit

__all__ = ["BlockCache", "BlockLayout", "CacheFetch", "VolumeImage"]

_VOXELS = BLOCK**3
VALUE_BITS = 16  # one voxel value field [I]


@dataclass(frozen=True)
class BlockLayout:
    """Where a 4^3 block's fill lives in SDRAM (the memory image above): blocks one after
    another, a value region of 16-bit voxels, then the gradient table (``gradient_bits``
    per difference, three per voxel) from the next page boundary.  One copy for the cycle
    rung's memory image and the transaction rung's bursts."""

    nb: tuple[int, int, int]
    blocks: int
    burst_length: int
    columns: int
    banks: int
    gradient_bits: int
    value_words: int
    gradient_words: int
    gradient_base: int
    value_bursts: int
    gradient_bursts: int

    @classmethod
    def of(
        cls, shape, sdram, voxel_bits: int, gradients: bool, source: str = "<built-in>"
    ) -> BlockLayout:
        """The layout of a ``shape`` volume; refused (key named) where its words do not
        hold whole voxels or the volume and gradient table do not fit the memory."""
        if sdram.word_bits % VALUE_BITS:
            raise InputError(
                f"{sdram.word_bits}-bit words do not hold whole {VALUE_BITS}-bit voxels",
                source=source,
                key="memory.word_bits",
                allowed=f"a multiple of {VALUE_BITS}",
            )
        nb = tuple(-(-n // BLOCK) for n in shape)
        blocks = int(np.prod(nb))
        # Central differences of voxel_bits-bit voxels span +-2 (2^bits - 1): that many
        # bits plus a sign, rounded up to whole bytes [I].
        gradient_bits = -(-((2 << voxel_bits).bit_length() + 1) // 8) * 8
        value_words = _VOXELS // (sdram.word_bits // VALUE_BITS)
        gradient_words = -(-_VOXELS * 3 * gradient_bits // sdram.word_bits)
        page = sdram.columns
        gradient_base = -(-blocks * value_words // page) * page
        pages = -(-(gradient_base + blocks * gradient_words) // page)
        if pages > sdram.banks * sdram.rows:
            raise InputError(
                f"the volume and its gradient table need {pages} pages of {page} words; "
                f"the memory has {sdram.banks * sdram.rows}",
                source=source,
                key="memory.rows",
                allowed=f">= {-(-pages // sdram.banks)}",
            )
        return cls(
            nb,  # type: ignore[arg-type]
            blocks,
            sdram.burst_length,
            page,
            sdram.banks,
            gradient_bits,
            value_words,
            gradient_words,
            gradient_base,
            -(-value_words // sdram.burst_length),
            -(-gradient_words // sdram.burst_length) if gradients else 0,
        )

    def bursts(self, blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bank and row of every READ burst filling ``blocks``, in order."""
        starts = [
            blocks[:, None] * self.value_words + np.arange(self.value_bursts) * self.burst_length
        ]
        if self.gradient_bursts:
            base = self.gradient_base + blocks[:, None] * self.gradient_words
            starts.append(base + np.arange(self.gradient_bursts) * self.burst_length)
        page = np.concatenate(starts, axis=1).ravel() // self.columns
        return page % self.banks, page // self.banks


@dataclass(frozen=True)
class CacheFetch:
    """The lookups of one step's issued samples.

    ``row (8, n)``: row of the step's line store (:attr:`store_values`) holding each
    corner's block as it was when the sample read it; ``offset (8, n)`` the voxel in the
    block; ``miss_samples`` the issue index of the sample behind each miss, in lookup
    order; ``miss_blocks`` the blocks filled.
    """

    row: np.ndarray
    offset: np.ndarray
    store_values: np.ndarray
    store_gradients: np.ndarray | None
    miss_samples: np.ndarray
    miss_blocks: np.ndarray

    def corners(self) -> np.ndarray:
        """``(8, n)`` voxel values of every sample's cell, as the cache delivered them."""
        return self.store_values[self.row, self.offset].astype(np.int64)

    def gradient_corners(self, sel: np.ndarray, channel: int) -> np.ndarray:
        """``(8, len(sel))`` gradient-table entries (``channel`` 0..2: dx, dy, dz)."""
        if self.store_gradients is None:
            return np.zeros((8, sel.size), dtype=np.int64)
        return self.store_gradients[channel][self.row[:, sel], self.offset[:, sel]].astype(np.int64)


class VolumeImage:
    """The volume as the host writes it into the card's SDRAM (values + gradient table).

    Parameters
    ----------
    raw : numpy.ndarray
        ``(nz, ny, nx)`` converted voxels (``Backend.raw``).
    memory : MemoryConfig
        The ``[memory]`` table (one 64-bit channel).
    voxel_bits : int
        Voxel width (sizes the gradient-table fields).
    gradients : bool
        Whether the gradient table is read (the scene uses gradients).
    stuck_word, stuck_bank : tuple, optional
        Faults: ``(address, value)``: every voxel of value word ``address`` reads
        ``value``; ``(bank, value)``: every voxel value in ``bank`` reads ``value`` and
        every gradient-table word in it reads 0.
    source : str
        The architecture file (error messages).
    volume : object, optional
        The volume ``raw`` was converted from: its fault-free image is kept with it
        (:func:`_blocks_of`) for the next frame.
    """

    def __init__(
        self,
        raw: np.ndarray,
        memory: MemoryConfig,
        *,
        voxel_bits: int,
        gradients: bool,
        stuck_word: tuple[int, int] | None = None,
        stuck_bank: tuple[int, int] | None = None,
        source: str = "<built-in>",
        volume: object | None = None,
    ) -> None:
        self.sd = sd = memory.sdram
        self.layout = lay = BlockLayout.of(raw.shape, sd, voxel_bits, gradients, source)
        self.shape, self.nb, self.blocks = raw.shape, lay.nb, lay.blocks
        self.value_words, self.gradient_words = lay.value_words, lay.gradient_words
        self.gradient_base = lay.gradient_base
        self.values, self.gradients = _blocks_of(raw, self.nb, voxel_bits, gradients, volume)
        if stuck_word is not None or stuck_bank is not None:  # written over: a copy
            self.values = self.values.copy()
            if self.gradients is not None:
                self.gradients = [g.copy() for g in self.gradients]
        per_word = sd.word_bits // VALUE_BITS
        if stuck_word is not None:
            address, value = stuck_word
            block, word = divmod(int(address), self.value_words)
            if 0 <= block < self.blocks:
                self.values[block, word * per_word : (word + 1) * per_word] = value
        if stuck_bank is not None:
            bank, value = stuck_bank
            words = np.arange(self.blocks * self.value_words).reshape(self.blocks, -1)
            hit = np.repeat(self._bank_of(words) == bank, per_word, axis=1)
            self.values[hit] = value
            if self.gradients is not None:
                starts = self.gradient_base + np.arange(self.blocks) * self.gradient_words
                in_bank = self._bank_of(starts) == bank
                for g in self.gradients:
                    g[in_bank] = 0

    def _bank_of(self, address: np.ndarray) -> np.ndarray:
        return (np.asarray(address) // self.sd.columns) % self.sd.banks

    def bursts(self, blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bank and row of every READ burst that fills ``blocks``, in order."""
        return self.layout.bursts(blocks)


class BlockCache:
    """Direct-mapped cache of 4^3-voxel blocks (tags and line storage).

    Parameters
    ----------
    sets : tuple of int
        ``(Sz, Sy, Sx)``: lines per block axis (``[buffers] cache_sets``).
    image : VolumeImage
        Where fills come from.
    corrupt_line, dropped_fill : optional
        Faults: ``(line, mask)`` XORs ``mask`` into every voxel value written into
        ``line``; ``k``: the ``k``-th fill (0-based) writes the tag but not the data.
    """

    def __init__(
        self,
        sets: tuple[int, int, int],
        image: VolumeImage,
        *,
        corrupt_line: tuple[int, int] | None = None,
        dropped_fill: int | None = None,
    ) -> None:
        self.sets = sets
        self.lines = int(np.prod(sets))
        self.image = image
        self.tag = np.full(self.lines, -1, dtype=np.int64)
        self.values = np.zeros((self.lines, _VOXELS), dtype=np.int32)
        self.gradients = None
        if image.gradients is not None:
            self.gradients = [np.zeros((self.lines, _VOXELS), dtype=np.int32) for _ in range(3)]
        self.corrupt_line = corrupt_line
        self.dropped_fill = dropped_fill
        self.fills = 0
        self.lookups = 0
        self.hits = 0

    def line_of(self, bz, by, bx) -> np.ndarray:
        sz, sy, sx = self.sets
        return ((bz % sz) * sy + by % sy) * sx + bx % sx

    def fetch(self, idx: np.ndarray) -> CacheFetch:
        """Look up the blocks of samples whose 8 voxels are ``idx (8, n)`` (flat volume
        indices, :func:`models.units.interp.interp_taps` order), in issue order."""
        ny, nx = self.image.shape[1], self.image.shape[2]
        nby, nbx = self.image.nb[1], self.image.nb[2]
        z, rem = np.divmod(idx, ny * nx)
        y, x = np.divmod(rem, nx)
        bz, by, bx = z >> 2, y >> 2, x >> 2
        offset = (((z & 3) << 2) | (y & 3)) << 2 | (x & 3)
        block = (bz * nby + by) * nbx + bx
        # Corner c reads the block of corner ``eff[c]``: c with the bits cleared of the
        # axes whose two voxels share a block.  Corners with eff == c look up a block.
        eff = np.empty_like(block)
        for c in range(8):
            e = np.full(block.shape[1], c, dtype=np.int64)
            for bit, b in ((4, bz), (2, by), (1, bx)):
                if c & bit:
                    e = np.where(b[c] == b[c & ~bit], e & ~bit, e)
            eff[c] = e
        looked = (eff == np.arange(8)[:, None]).T  # (n, 8), sample-major lookup order
        n_look = int(looked.sum())
        look_sample, look_corner = np.nonzero(looked)
        look_block = block[look_corner, look_sample]
        line = self.line_of(bz, by, bx)[look_corner, look_sample]
        order = np.argsort(line, kind="stable")
        s_line, s_tag = line[order], look_block[order]
        first = np.ones(n_look, dtype=bool)
        first[1:] = s_line[1:] != s_line[:-1]
        prev = np.empty(n_look, dtype=np.int64)
        prev[1:] = s_tag[:-1]
        prev[first] = self.tag[s_line[first]]
        s_miss = prev != s_tag
        miss = np.empty(n_look, dtype=bool)
        miss[order] = s_miss
        fill_no = np.cumsum(miss) - 1  # fills numbered in lookup order
        # Row of the store holding each lookup's block: a miss its own fill; a hit the
        # last fill of its line earlier in this step, else the line as it was.
        pos = np.arange(n_look)
        last_miss = np.maximum.accumulate(np.where(s_miss, pos, -1))
        group_start = np.maximum.accumulate(np.where(first, pos, 0))
        s_row = np.where(s_miss, self.lines + fill_no[order], s_line)
        carried = (last_miss >= group_start) & ~s_miss
        s_row[carried] = s_row[last_miss[carried]]
        row_of_look = np.empty(n_look, dtype=np.int64)
        row_of_look[order] = s_row
        fills = look_block[miss]
        fill_lines = line[miss]
        new_values = self.image.values[fills]
        new_grads = None
        if self.gradients is not None:
            new_grads = [g[fills] for g in self.image.gradients]
        if self.corrupt_line is not None and fills.size:
            hit_line = fill_lines == self.corrupt_line[0]
            new_values[hit_line] ^= np.int32(self.corrupt_line[1])
        k = self.dropped_fill
        if k is not None and self.fills <= k < self.fills + fills.size:
            i = k - self.fills
            earlier = np.flatnonzero(fill_lines[:i] == fill_lines[i])
            src = self.lines + earlier[-1] if earlier.size else fill_lines[i]
            new_values[i] = self._store_row(self.values, new_values, src)
            if new_grads is not None:
                for g, ng in zip(self.gradients, new_grads, strict=True):
                    ng[i] = self._store_row(g, ng, src)
        store_values = np.concatenate([self.values, new_values])
        store_grads = None
        if new_grads is not None:
            store_grads = [
                np.concatenate([g, ng]) for g, ng in zip(self.gradients, new_grads, strict=True)
            ]
        # Line state after the step: each line's last lookup.
        last = np.ones(n_look, dtype=bool)
        last[:-1] = s_line[1:] != s_line[:-1]
        lines_done, rows_done = s_line[last], s_row[last]
        self.tag[lines_done] = s_tag[last]
        self.values[lines_done] = store_values[rows_done]
        if store_grads is not None:
            for g, sg in zip(self.gradients, store_grads, strict=True):
                g[lines_done] = sg[rows_done]
        self.fills += int(fills.size)
        self.lookups += n_look
        self.hits += n_look - int(fills.size)
        look_index = np.full(looked.shape, -1, dtype=np.int64)
        look_index[looked] = np.arange(n_look)
        n = idx.shape[1]
        corner_look = look_index[np.arange(n)[None, :], eff]  # (8, n)
        return CacheFetch(
            row=row_of_look[corner_look],
            offset=offset,
            store_values=store_values,
            store_gradients=store_grads,
            miss_samples=look_sample[miss],
            miss_blocks=fills,
        )

    def _store_row(self, lines: np.ndarray, new: np.ndarray, row: int) -> np.ndarray:
        return (lines[row] if row < self.lines else new[row - self.lines]).copy()


#: Fault-free memory images (voxel and gradient blocks) by volume, then by the voxel
#: width and whether the gradient table is read: successive frames of one volume
#: build them once (as the functional kernel keeps its laid-out voxels); dropped with the
#: volume.
_IMAGES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _blocks_of(raw: np.ndarray, nb, voxel_bits: int, gradients: bool, volume: object | None):
    """``(values, gradient blocks or None)`` of ``raw`` (:func:`_to_blocks`), kept with
    ``volume`` when given; callers that write into them copy first."""
    kept = _IMAGES.setdefault(volume, {}) if volume is not None else {}
    key = (raw.shape, voxel_bits, gradients)
    if key not in kept:
        grads = None
        if gradients:
            diffs = gradient_unit.voxel_differences(raw)
            grads = [_to_blocks(d.reshape(raw.shape), nb) for d in diffs]
        kept[key] = (_to_blocks(raw, nb), grads)
    return kept[key]


def _to_blocks(data: np.ndarray, nb: tuple[int, int, int]) -> np.ndarray:
    """``(blocks, 64)`` int32: the volume block by block (edge blocks padded by repeating
    edge voxels; padding is never read by a sample)."""
    pad = [(0, b * BLOCK - n) for n, b in zip(data.shape, nb, strict=True)]
    padded = np.pad(np.asarray(data), pad, mode="edge") if any(p[1] for p in pad) else data
    cubes = padded.reshape(nb[0], BLOCK, nb[1], BLOCK, nb[2], BLOCK).transpose(0, 2, 4, 1, 3, 5)
    return np.ascontiguousarray(cubes.reshape(-1, _VOXELS)).astype(np.int32)
