"""The VolumePro-family transaction model's chunk reads: each module's burst stream and
the reads handed to the SDRAM ports late and in bulk.

# Ref: docs/transaction.md "The VolumePro 500 / EM-Cube event model" (the memory
#      process); hwsim/memory/sdram_events.py (SdramTransactionPort.read_runs).

:class:`ChunkStreams` holds every chunk's bursts split by module (built by
:func:`chunk_streams`, laying out only the mini-blocks a chunk reads);
:class:`DeferredReads` records when each chunk issues and hands the ports every chunk
issued so far when the pipelines first ask when one is ready; :func:`memory_process`
issues the chunks on its own clock, told by the pipelines through :class:`ChunkLink`
when each buffer slot is freed.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
import simpy

from models.machines.volumepro.lanes import miniblock_layout
from models.machines.volumepro.memory import mini_block_bursts

__all__ = [
    "ChunkLink",
    "ChunkStreams",
    "DeferredReads",
    "chunk_streams",
    "lend_logs",
    "memory_process",
    "return_logs",
]

#: Bursts of the slab layouts kept for the next frame (a 256^3 volume's 2 Mi with one
#: word a voxel); larger volumes are laid out again each frame.
_KEEP = 1 << 22
#: The last slab layouts, by voxel layout and view axes (:func:`slab_layouts`).
_layouts: dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
#: The kept layout's bank and row ranges ``(min, max, min, max)``, by the same key.
_layout_ranges: dict[tuple, tuple[int, int, int, int]] = {}
#: Requests of the SDRAM request logs kept for later frames, in all (:func:`lend_logs`).
_POOL_REQUESTS = 1 << 21
#: Request logs (``out``, ``arrivals``) of finished frames' controllers, free to reuse.
_pool: list[tuple[np.ndarray, np.ndarray]] = []
_pool_lock = threading.Lock()
#: The module streams (``banks``, ``rows``) of a finished frame, free to reuse (up to
#: :data:`_KEEP` entries each).
_streams_kept: list[tuple[np.ndarray, np.ndarray]] = []


@dataclass
class ChunkStreams:
    """Per module ``(bank, row, bounds, per)``: its bursts of every chunk in read order,
    chunk ``c``'s bursts at ``bounds[c] .. bounds[c + 1] - 1``, ``per[c]`` of them;
    ``batches[c]``: modules chunk ``c`` reads from."""

    modules: list[tuple[np.ndarray, np.ndarray, list[int], np.ndarray]]
    batches: list[int]
    #: The ``(modules, >= bursts)`` arrays the streams are rows of (kept for later frames).
    scratch: tuple[np.ndarray, ...] = ()


def slab_layouts(model: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Module, bank and row of every burst of every slab's mini-block beams, ``(slabs,
    n_u, n_mb words_per_voxel)``: mbb ``u`` of slab ``s`` holds voxel rows ``2u, 2u + 1``
    of voxel slices ``2s, 2s + 1``, its mini-blocks along the beam in read order, a
    mini-block's bursts back to back.  ``model``: the
    :class:`~models.machines.volumepro.transaction.SlabTransaction`.  The layout is the
    volume's, not the view's: the last one (up to :data:`_KEEP` bursts) is kept for the
    next frame with the same memory, volume size and axes."""
    n_mb, wpv = -(-model.n_b // 2), model.words_per_voxel
    key = _layout_key(model)
    if key in _layouts:
        return _layouts[key]
    shape = (model.n_slabs, model.n_u, n_mb * wpv)
    out = (np.empty(shape, np.int16), np.empty(shape, np.int16), np.empty(shape, np.int64))
    coords: list[Any] = [None, None, None]
    coords[model.a_ax] = np.repeat(2 * np.arange(model.n_u)[:, None], n_mb, axis=1)
    coords[model.b_ax] = np.repeat(2 * np.arange(n_mb)[None, :], model.n_u, axis=0)
    for slab in range(model.n_slabs):  # a slab at a time: the temporaries stay small
        coords[model.kp] = np.full((model.n_u, n_mb), 2 * slab)
        module, bank, address = miniblock_layout(
            model.memory, model.n_even, coords[2], coords[1], coords[0]
        )
        bursts = mini_block_bursts(model.memory, module, bank, address, wpv)
        for whole, part in zip(out, bursts, strict=True):
            whole[slab] = part
    if out[0].size <= _KEEP:
        _layouts.clear()
        _layouts[key] = out
        _layout_ranges.clear()
        if out[1].size:
            _layout_ranges[key] = (out[1].min(), out[1].max(), out[2].min(), out[2].max())
    return out


def _layout_key(model: Any) -> tuple:
    axes, n_mb = (model.kp, model.a_ax, model.b_ax), -(-model.n_b // 2)
    wpv = model.words_per_voxel
    return (repr(model.memory), model.n_even, axes, model.n_slabs, model.n_u, n_mb, wpv)


def _layout_in_range(model: Any, banks: int, rows: int) -> bool:
    """Whether the kept layout of ``model`` (:func:`slab_layouts`) has every bank in
    ``0 .. banks - 1`` and row in ``0 .. rows - 1``: so has every burst read from it."""
    b0, b1, r0, r1 = _layout_ranges.get(_layout_key(model), (-1, -1, -1, -1))
    return b0 >= 0 and b1 < banks and r0 >= 0 and r1 < rows


def chunk_streams(model: Any, chunks: list[tuple[int, int, int, int]]) -> ChunkStreams:
    """Every chunk's bursts (mini-blocks read: all, or with skipping those a live cell
    needs, ``model.skips.needed``), split by module into one stream each in read order,
    checked against the device once.  ``model``: the
    :class:`~models.machines.volumepro.transaction.SlabTransaction`; ``chunks``: its
    ``(band, slab, u_lo, u_hi)`` in read order.  The split is compiled
    (:func:`~models.machines.volumepro.streams_kernel.split_streams`) over the slab
    layouts (:func:`slab_layouts`)."""
    from models.machines.volumepro.streams_kernel import bursts_read, split_streams  # numba

    M, cfg, nc = model.memory.modules, model.memory.sdram, len(chunks)
    if not nc:
        empty = np.zeros(0, np.int64)
        return ChunkStreams([(empty, empty, [0], empty)] * M, [])
    spans = np.array([(slab, lo, hi + 1) for _, slab, lo, hi in chunks], dtype=np.int64)
    sk = model.skips
    needed = np.zeros((0, 0, 0), dtype=bool) if sk is None else sk.needed
    module, bank, row = slab_layouts(model)
    wpv = model.words_per_voxel
    total = bursts_read(spans, needed, module.shape[2] // wpv, wpv)
    banks, rows = _stream_arrays(M, total)
    per = split_streams(module, bank, row, spans, needed, wpv, banks, rows)
    bounds = np.zeros((M, nc + 1), dtype=np.int64)
    np.cumsum(per, axis=1, out=bounds[:, 1:])
    used = [(banks[k, :n], rows[k, :n]) for k, n in enumerate(bounds[:, -1])]
    in_range = _layout_in_range(model, cfg.banks, cfg.rows)  # else the bursts read checked
    for i, (name, limit) in enumerate(() if in_range else (("bank", cfg.banks), ("row", cfg.rows))):
        if any(v.size and (v.min() < 0 or v.max() >= limit) for v in (u[i] for u in used)):
            raise ValueError(f"{name} out of range 0 .. {limit - 1}")
    modules = [(b, r, bounds[k].tolist(), per[k]) for k, (b, r) in enumerate(used)]
    return ChunkStreams(modules, (per > 0).sum(axis=0).tolist(), (banks, rows))


def _stream_arrays(modules: int, total: int) -> tuple[np.ndarray, np.ndarray]:
    """``banks`` and ``rows`` for :func:`split_streams`: a finished frame's if they fit
    (their pages mapped already; every entry read is written first), else new."""
    with _pool_lock:
        for i, (banks, _) in enumerate(_streams_kept):
            if banks.shape[0] == modules and banks.shape[1] >= total:
                return _streams_kept.pop(i)
    return np.empty((modules, total), np.int64), np.empty((modules, total), np.int64)


class DeferredReads:
    """The chunks' SDRAM reads, handed to the modules' ports only when the pipelines ask
    when a chunk is ready: the controller is causal (a burst's cycles depend on the
    bursts before it and their arrival cycles only), so every chunk issued so far goes in
    one call per module with its own arrival cycle, the same schedule as a call per chunk
    when it issued.  The memory runs about a buffer ahead of the pipelines, so a frame
    makes a few calls per buffer's worth of chunks, not one per chunk and module."""

    def __init__(self, ports, streams: ChunkStreams, nc: int, frames: int) -> None:
        self.ports, self.streams, self.nc = ports, streams, nc
        self.issue_at: list[int] = []  # cycle each chunk issued, in read order
        self.ready: list[int] = []  # cycle each flushed chunk is ready
        for port, (bank, _, _, _) in zip(ports, streams.modules, strict=True):
            lend_logs(port.controller, frames * bank.size)

    def release(self) -> None:
        """Keep the ports' request logs and the streams' arrays for later frames (call
        once the schedules are read: the next frame overwrites them)."""
        return_logs(self.ports)
        scratch = self.streams.scratch
        if scratch and scratch[0].size <= _KEEP:
            with _pool_lock:
                _streams_kept[:] = [scratch]

    @property
    def issued_count(self) -> int:
        return len(self.issue_at)

    def issued(self, c: int) -> bool:
        return c < len(self.issue_at)

    def issue(self, now: int, g: int, h: int) -> int:
        """Chunks ``g .. h - 1`` issue at cycle ``now``; returns the events the model
        counts for them (one per module batch and one per chunk's readiness)."""
        self.issue_at.extend([now] * (h - g))
        nc = self.nc
        return sum(self.streams.batches[c % nc] for c in range(g, h)) + (h - g)

    def ready_by(self, c: int, now: float) -> bool:
        """Whether chunk ``c`` has issued and its bursts have all arrived by ``now``."""
        return c < len(self.issue_at) and self.ready_at(c) <= now

    def ready_at(self, c: int) -> int:
        """Cycle chunk ``c`` (issued) is ready: its last burst on every module delivered."""
        if c >= len(self.ready):
            self.flush(len(self.issue_at))
        return self.ready[c]

    def flush(self, upto: int) -> None:
        """Hand chunks ``len(self.ready) .. upto - 1`` to the ports (frame by frame)."""
        nc = self.nc
        a = len(self.ready)
        while a < upto:
            f = a // nc
            b = min(upto, (f + 1) * nc)
            c0, c1 = a - f * nc, b - f * nc
            at = np.asarray(self.issue_at[a:b], dtype=np.int64)
            ready = at.copy()
            for port, (bank, row, bounds, per) in zip(
                self.ports, self.streams.modules, strict=True
            ):
                lo, hi = bounds[c0], bounds[c1]
                if hi > lo:
                    arrive = np.repeat(at, per[c0:c1])
                    ends = np.cumsum(per[c0:c1])  # bounds[c0 + 1 .. c1] - lo
                    done = port.read_runs(bank[lo:hi], row[lo:hi], arrive, ends)
                    np.maximum(ready, done, out=ready)
            self.ready.extend(ready.tolist())
            a = b


def lend_logs(controller, n: int) -> None:
    """Give ``controller`` request logs for ``n`` requests: the smallest kept ones that
    fit (:func:`return_logs`), else new ones of exactly ``n``.  A kept log's pages are
    already mapped: fresh ones cost a page fault every 4 KiB on their first write (~2,000
    faults, a sixth of a 128^3 VolumePro 1000 frame's timing-only CPU time); the
    controller overwrites every entry it later reads, so nothing of another frame leaks."""
    with _pool_lock:
        fits = [k for k, (_, a) in enumerate(_pool) if a.shape[0] >= n]
        logs = _pool.pop(min(fits, key=lambda k: _pool[k][1].shape[0])) if fits else None
    if logs is None:
        m, rows = max(int(n), 1), controller.logs()[0].shape[0]
        logs = np.empty((rows, m), dtype=np.int64), np.empty(m, dtype=np.int64)
    controller.adopt_logs(*logs)


def return_logs(ports) -> None:
    """Keep the request logs of ``ports``' controllers for later frames (up to
    :data:`_POOL_REQUESTS` requests in all): call only once their schedules are read."""
    with _pool_lock:
        kept = sum(a.shape[0] for _, a in _pool)
        for port in ports:
            out, arrivals = port.controller.logs()
            if kept + arrivals.shape[0] <= _POOL_REQUESTS:
                _pool.append((out, arrivals))
                kept += arrivals.shape[0]


class ChunkLink:
    """What the memory and pipelines processes share: the deferred reads, the cycle each
    chunk's buffer slot was freed (-1: not yet), and who waits for whom."""

    def __init__(self, env: simpy.Environment, reads: DeferredReads, total: int) -> None:
        self.env, self.reads, self.total = env, reads, total
        self.free_at = [-1] * total
        self.waiting: list[Any] = [None, None]  # the chunk the pipelines wait to see issued
        self.memory_waits: list[Any] = [-1, None]  # the slot the memory waits to see freed

    def free(self, c: int, t: int) -> None:
        """Chunk ``c``'s slot is freed at cycle ``t``."""
        self.free_at[c] = t
        if self.memory_waits[0] == c:
            self.memory_waits[0] = -1
            self.memory_waits[1].succeed()

    def sync(self, t: int):
        """Process step: bring SimPy's clock to a process's own clock ``t``."""
        if t > self.env.now:
            yield self.env.timeout(t - self.env.now)


def memory_process(link: ChunkLink, cap: int, stats: dict):
    """The memory process: chunk ``g`` issues at the later of chunk ``g - 1``'s issue
    and the freeing of chunk ``g - cap``'s slot (a run free at one cycle issues
    together); it yields only while that slot's freeing is not known yet."""
    env, reads, free_at = link.env, link.reads, link.free_at
    g, now = 0, 0
    while g < link.total:
        if g >= cap:
            while free_at[g - cap] < 0:  # the pipelines have not freed it yet
                link.memory_waits = [g - cap, env.event()]
                yield link.memory_waits[1]
            if free_at[g - cap] > now:
                stats["buffer_full"] += free_at[g - cap] - now
                now = free_at[g - cap]
        h = g + 1
        while h < link.total and (h < cap or 0 <= free_at[h - cap] <= now):
            h += 1
        stats["events"] += reads.issue(now, g, h)
        g = h
        if link.waiting[0] is not None and link.waiting[0] < h:
            link.waiting[1].succeed()
            link.waiting[0] = None
