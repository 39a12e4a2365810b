"""One Cube-4 slice on its way from the memory modules to the interpolators.

# Ref: architectures.md sections 1.2-1.3 (the beam arrives rotated; x-neighbours come from
#      pipeline k+1 over the ring, y-neighbours from a one-beam delay FIFO, z-neighbours
#      from slice delay FIFOs) and 9.2 (beam delay n/P, slice delay n^2/P per pipeline).

Pipeline ``m`` holds voxel ``(a, b)`` of slice ``s`` at cycle ``t = a C + b div P`` when
``(s + a + b) mod P = m``.  The sample cell whose origin is that voxel needs its three
other corners, which live in modules ``m + 1`` and ``m + 2``:

* ``(a, b + 1)``: pipeline ``m + 1`` over ring link ``m`` -- the same cycle, or the next
  when ``b`` ends a group of P (``b mod P = P - 1``);
* ``(a + 1, b)``: pipeline ``m + 1``, one beam (``C`` cycles) later;
* ``(a + 1, b + 1)``: pipeline ``m + 2`` over two links, ``C`` or ``C + 1`` cycles later.

So the cell is evaluated at ``t + C + 1`` with its corners taken from delay lines of
depth ``C + 1`` (the beam FIFO), ``C + 1`` / ``C``, ``1`` and ``1`` / ``0``.  Ring link
``k`` carries data from pipeline ``k + 1`` to ``k``; a dropped link delivers zeros.
Cells on the far edges replicate their own voxels (the golden renderer's clamp), and the
cell grid is extended to ``[-2, n]`` the same way, so sample positions in
``[-0.5, n - 0.5]`` and their gradient neighbours one voxel away all find their cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.engine import Counters

__all__ = ["SliceDatapath", "SlicePath", "extend_axis"]


@dataclass(frozen=True, kw_only=True)
class SlicePath:
    """Depths and faults of the ring links and beam FIFO of every pipeline.

    ``beam_fifo_depth`` defaults to ``C + 1``; ``dropped_link`` is the ring link (from
    pipeline ``k + 1`` to ``k``) that delivers nothing, or None.
    """

    pipelines: int
    beam_fifo_adjust: int = 0
    dropped_link: int | None = None


def extend_axis(v0: np.ndarray, v1: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Corner-0 / corner-1 planes of cells ``[0, n)`` extended to cells ``[-2, n]``.

    Cell ``c`` has corners ``clamp(c)`` and ``clamp(c + 1)``: cells ``-2, -1`` take
    voxel 0 twice, cell ``n`` voxel ``n - 1`` twice (``v1[n - 1]`` already is it).
    """
    n = v0.shape[axis]
    idx0 = np.clip(np.arange(-2, n + 1), 0, n - 1)
    e0 = np.take(v0, idx0, axis=axis)
    head = np.take(v0, [0, 0], axis=axis)
    tail = np.take(v1, [n - 1], axis=axis)
    e1 = np.concatenate([head, v1, tail], axis=axis)
    return e0, e1


class SliceDatapath:
    """Ring links and beam delay FIFOs of all pipelines, applied to one slice's stream."""

    def __init__(self, path: SlicePath, shape_ab: tuple[int, int], counters: Counters) -> None:
        self.path, self.counters = path, counters
        self.P = P = path.pipelines
        self.n_a, self.n_b = shape_ab
        self.C = -(-self.n_b // P)
        self.beam_depth = self.C + 1 + path.beam_fifo_adjust
        if self.beam_depth < 0:
            raise ValueError(f"beam FIFO depth {self.beam_depth} < 0")
        a = np.arange(self.n_a)[:, None]
        b = np.arange(self.n_b)[None, :]
        self._cell_t = a * self.C + b // P + self.C + 1  # evaluation cycle of each cell
        self._wrap = np.broadcast_to(b % P == P - 1, (self.n_a, self.n_b))
        self._b = b
        self._a = a
        self._read_cache: dict = {}
        self._route_cache: dict = {}
        counters.set("ring.beam_fifo_depth", self.beam_depth)

    def clear_caches(self) -> None:
        """Drop the precomputed reads and routes (up to 16 of each, a slice's cells
        several times over: ~0.15 GB at 512^2) once the frame moves no more slices."""
        self._read_cache.clear()
        self._route_cache.clear()

    def _reads(self, residue: int, L: int) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """Per delay depth: where each cell reads the ``(P, L)`` stream, and which cells
        read before anything left the line (reset zeros).  Depends on ``s mod P`` only;
        the same as :meth:`DelayLine.read_at`, precomputed."""
        key = (residue, L)
        if key not in self._read_cache:
            if len(self._read_cache) >= 16:  # P = 256 has 256 residues: keep the latest
                self._read_cache.pop(next(iter(self._read_cache)))
            t = self._cell_t
            flat = ((residue + self._a + self._b) % self.P) * L + t
            depths = {self.beam_depth, self.C, self.C + 1, 1, 0}
            self._read_cache[key] = {
                d: (np.maximum(flat - d, 0), np.broadcast_to(t < d, t.shape).copy()) for d in depths
            }
        return self._read_cache[key]

    def _link(self, stream: np.ndarray) -> np.ndarray:
        """What every pipeline receives over its ring link: pipeline ``k + 1``'s stream."""
        out = np.roll(stream, -1, axis=0)
        if self.path.dropped_link is not None:
            out[self.path.dropped_link] = 0
        return out

    def corners(self, stream: np.ndarray, s: int) -> np.ndarray:
        """The four corner planes ``(4, n_a + 3, n_b + 3)`` of slice ``s``.

        Which stream entry reaches which corner of which cell depends only on ``s mod P``
        (and on the link, FIFO and fault settings), never on the data: :meth:`_route`
        runs the datapath once on a stream of entry numbers, and every slice then moves
        its voxels along those routes with one gather.
        """
        routes = self._route(s % self.P, stream.shape[1])
        source = np.zeros(self.P * (stream.shape[1] + self.C + 1) + 1, dtype=stream.dtype)
        source[1:].reshape(self.P, -1)[:, : stream.shape[1]] = stream  # entry 0 reads as 0
        return np.take(source, routes)

    def _route(self, residue: int, length: int) -> np.ndarray:
        """Entry numbers (1-based, 0 = nothing arrives) at every corner of every cell."""
        key = (residue, length)
        if key not in self._route_cache:
            if len(self._route_cache) >= 16:
                self._route_cache.pop(next(iter(self._route_cache)))
            # A slice's stream followed by C + 1 flush cycles, numbered entry by entry.
            entries = np.arange(1, self.P * (length + self.C + 1) + 1).reshape(self.P, -1)
            self._route_cache[key] = self._carry(entries, residue)
        return self._route_cache[key]

    def _carry(self, ext: np.ndarray, s: int) -> np.ndarray:
        """Move a ``(P, T + C + 1)`` stream (a slice plus its flush cycles) through the ring
        links, the delay lines and the boundary multiplexers to every cell's corners."""
        P, C, L = self.P, self.C, ext.shape[1]
        ring1 = self._link(ext)
        ring2 = self._link(ring1)
        reads = self._reads(s % P, L)

        def delayed(x: np.ndarray, depth: int) -> np.ndarray:
            # The delay line of that depth (reset per slice), read at each cell's cycle.
            idx, fresh = reads[depth]
            out = x.ravel()[idx]
            out[fresh] = 0
            return out

        v00 = delayed(ext, self.beam_depth)
        v01 = np.where(self._wrap, delayed(ring1, C), delayed(ring1, C + 1))
        v10 = delayed(ring1, 1)
        v11 = np.where(self._wrap, delayed(ring2, 0), delayed(ring2, 1))
        # Far-edge cells replicate their own voxels (boundary multiplexers).
        last_b = self._b == self.n_b - 1
        v01 = np.where(last_b, v00, v01)
        v11 = np.where(last_b, v10, v11)
        if self.n_a >= 1:
            v10[-1] = v00[-1]
            v11[-1] = v01[-1]
        e00, e01 = extend_axis(v00, v01, 1)
        e10, e11 = extend_axis(v10, v11, 1)
        E00, E10 = extend_axis(e00, e10, 0)
        E01, E11 = extend_axis(e01, e11, 0)
        return np.stack([E00, E01, E10, E11])


@dataclass(frozen=True)
class SliceSchedule:
    """Which voxel each pipeline reads at each cycle of one slice.

    ``a``, ``b`` are ``(P, T)`` in-slice coordinates (``b >= n_b`` marks an idle slot),
    ``valid`` the slots that read a voxel, ``zyx`` the ``(3, P, T)`` volume coordinates.
    """

    a: np.ndarray
    b: np.ndarray
    valid: np.ndarray
    zyx: tuple[np.ndarray, np.ndarray, np.ndarray]


def slice_schedule(
    shape: tuple[int, int, int], P: int, kp: int, s: int, cache: dict | None = None
) -> SliceSchedule:
    """Which voxel each of P pipelines receives at each clock of slice ``s`` along ``kp``
    of a ``shape`` volume: the Cube-4 stream order (also the VolumePro de-skew network's
    output).  ``cache`` (a dict) keeps the ``(a, b)`` arrays per ``(kp, s mod P)``."""
    axes = [ax for ax in range(3) if ax != kp]
    n_a, n_b = shape[axes[0]], shape[axes[1]]
    C = -(-n_b // P)
    key = (kp, s % P)
    cache = {} if cache is None else cache
    if key not in cache:
        m = np.arange(P)[:, None]
        t = np.arange(n_a * C)[None, :]
        a = np.broadcast_to(t // C, (P, n_a * C))
        b = (t % C) * P + (m - s - a) % P
        cache[key] = (a, b)
    a, b = cache[key]
    valid = b < n_b
    coords: list[np.ndarray] = [None, None, None]  # type: ignore[list-item]
    coords[kp] = np.full(a.shape, s, dtype=np.int64)
    coords[axes[0]] = a
    coords[axes[1]] = np.where(valid, b, 0)
    return SliceSchedule(a, b, valid, (coords[0], coords[1], coords[2]))
