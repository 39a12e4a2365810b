"""The VolumePro family's slice loads compiled: a voxel slice from the SDRAM words to the
corner planes its cells read, and the voxel differences of VolumePro 1000's gradient unit.

# Ref: architectures.md sections 3 (mini-blocks in SDRAM, the de-skew network) and 9.1-9.2
#      (ring links and beam FIFOs); models/machines/volumepro/memory.py (the layout, the
#      faults of the modules and banks); models/machines/common/slices.py (the ring).

Where a voxel of a slice goes never depends on its value: the de-skew network puts voxel
``(a, b)`` at one slot of the ``(P, T)`` stream (:meth:`SdramVolume.schedule`), and the ring
links, beam FIFOs and boundary multiplexers take each cell's corners from fixed slots or
from nothing (:meth:`SliceDatapath.corners`, which moves any stream along the same routes).
So the routes are found once per ``q mod P`` by sending the stream of voxel numbers
(``1 + a n_b + b``, 0 in idle slots) through :meth:`SliceDatapath.corners`: a cell
corner then reads voxel ``number - 1`` of the slice or 0, whatever the stream carries.
They depend on the ring (its depths and faults), the slice shape and ``q mod P`` alone,
so they are kept across frames (:data:`_ROUTES`, read-only, bounded).
Each slice is then three compiled, GIL-free passes instead of the NumPy chain
(stream read, de-skew, ring gather, shift, per channel): :func:`read_plane`
(the words at the layout's addresses, the stuck module and bank), :func:`_value_rows`
(corners shifted to the samples' fraction bits, the slice's voxel plane and the
transparency bounds of each cell) and :func:`_voxel_differences` (central differences of
the delivered voxels, kept per voxel: the compiled stage reads a visible sample's corners
through the same routes, so only the planes the unit chain asks for are gathered, by
:class:`CornerPlanes`, into the rows the NumPy form streamed through the de-skew network
and ring).  ``tests/models/test_slice_loads.py`` compares them with the
NumPy form (kept: pre-classified frames, and the reference) on every fault that moves data.
"""

from __future__ import annotations

import threading

import numba
import numpy as np

from models.units import classify as classify_unit

__all__ = ["CornerPlanes", "SliceLoads", "differences_numpy", "load_numpy", "read_plane", "visible"]


class SliceLoads:
    """The compiled slice loads of one :class:`~models.machines.volumepro.cycle.SlabMachine`
    frame: the cells' routes per ``q mod P``, the loads and the voxel differences."""

    def __init__(self, machine) -> None:
        self.m = machine
        self.S = machine.dp.interp.sample_frac_bits
        self._routes: dict[int, np.ndarray] = {}
        cfg = machine.dp.classify
        self.lut_shift = machine.dp.voxel_bits + self.S - int(np.log2(cfg.entries))
        self.entries = int(cfg.entries)
        # Narrow where they fit (half the bytes the compiled passes stream per sample):
        # the routes' voxel numbers, and the differences (at most twice a voxel's range,
        # shifted by the fraction bits).
        mem = machine.memory
        stuck = [*(mem.stuck_module or (0, 0))[1:], *(mem.stuck_bank or (0, 0, 0))[2:]]
        word = max(16, *(abs(int(v)).bit_length() for v in stuck))  # uint16 words
        self.index_type = _fits(int(machine.n_a * machine.n_b + 1).bit_length())
        self.diff_type = _fits(word + 2 + self.S)
        # The LUT entries of each cell's corners (``visible`` reads two slices' per sample).
        self.entry_type = np.int16 if self.entries <= 1 << 15 else np.int64

    def routes(self, q: int) -> np.ndarray:
        """``(cells, 4)``, int32 where it fits: the voxel number (``1 + a n_b + b``, 0:
        nothing) each corner of each cell of slice ``q`` receives (depends on ``q mod P``
        alone)."""
        m = self.m
        routes = self._routes.get(q % m.P)
        if routes is None:
            key = (m.datapath.path, m.P, m.n_a, m.n_b, q % m.P, np.dtype(self.index_type).str)
            with _ROUTES_LOCK:
                routes = _ROUTES.get(key)
            if routes is None:
                sched = m.memory.schedule(m.kp, q)
                numbers = np.where(sched.valid, sched.a * m.n_b + sched.b + 1, 0)
                corners = m.datapath.corners(numbers.astype(np.int64), q).reshape(4, -1).T
                routes = np.ascontiguousarray(corners, dtype=self.index_type)
                routes.setflags(write=False)
                _keep_routes(key, routes)
            self._routes[q % m.P] = routes
        return routes

    def load(self, q: int) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """Corner planes of voxel slice ``q`` (``value`` and, when transparent cells are
        skipped, ``lo`` / ``hi``) and its delivered voxel plane ``(n_a, n_b)``."""
        m = self.m
        plane = read_plane(m.memory, m.kp, q)
        routes = self.routes(q)
        n = routes.shape[0]
        rows = np.empty((n, 4), dtype=np.int64)
        want = m.skip_transparent
        lo = np.empty(n if want else 0, dtype=self.entry_type)
        hi = np.empty_like(lo)
        voxels = np.empty((m.n_a, m.n_b), dtype=np.int64)
        _value_rows(
            plane.ravel(), routes, self.S, rows, voxels, m.n_b + 3,
            want, self.lut_shift, self.entries, lo, hi,
        )  # fmt: skip
        planes = CornerPlanes(lo=lo, hi=hi) if want else CornerPlanes()
        planes["value"] = rows
        return planes, voxels

    def differences(self, q: int, lo: np.ndarray, hi: np.ndarray, factor: int, cur: np.ndarray):
        """The voxel differences of slice ``q`` as :class:`CornerPlanes` entries ``diff``
        (``(n_a n_b + 1, 3)``: row ``1 + a n_b + b`` the differences at voxel ``(a, b)``
        along volume axes z, y, x, shifted left by the samples' fraction bits; row 0 the
        zeros of a corner nothing reaches) and ``routes`` (:meth:`routes`): ``factor (hi -
        lo)`` along the principal axis, central differences of ``cur`` in the slice
        (``2 (v[1] - v[0])`` at its edges).  The compiled stage reads a visible sample's
        corners through the routes; ``dx``, ``dy``, ``dz`` corner planes are gathered only
        when asked for (:meth:`CornerPlanes.__missing__`)."""
        m = self.m
        n_a, n_b = cur.shape
        diff = np.empty((n_a * n_b + 1, 3), dtype=self.diff_type)
        _voxel_differences(
            np.ascontiguousarray(lo), np.ascontiguousarray(hi), factor,
            np.ascontiguousarray(cur), self.S, m.kp, m.a_ax, m.b_ax, diff,
        )  # fmt: skip
        return CornerPlanes(diff=diff, routes=self.routes(q))


#: The routes of this process's frames by ring (its depths and faults: ``SlicePath``),
#: pipelines, slice shape and ``q mod P``: a property of the layout and the ring alone,
#: never of the data or the view (like the memory's skew conflicts,
#: ``memory._slice_conflicts``), so a turntable's frames find them once.  Read-only, at
#: most :data:`_ROUTES_BYTES` in all (the oldest dropped first).
_ROUTES: dict[tuple, np.ndarray] = {}
_ROUTES_BYTES = 64 << 20
_ROUTES_LOCK = threading.Lock()


def _keep_routes(key: tuple, routes: np.ndarray) -> None:
    """Keep ``routes`` in :data:`_ROUTES`, dropping the oldest beyond its budget."""
    with _ROUTES_LOCK:
        _ROUTES[key] = routes
        while sum(r.nbytes for r in _ROUTES.values()) > _ROUTES_BYTES and len(_ROUTES) > 1:
            _ROUTES.pop(next(iter(_ROUTES)))


def _fits(bits: int) -> type:
    """int32 for values of at most ``bits`` bits and a sign, else int64."""
    return np.int32 if bits < 32 else np.int64


class CornerPlanes(dict):
    """A voxel slice's corner planes by channel (``(cells, 4)`` int64 rows), whose voxel
    differences are kept per voxel (``diff``, ``routes``: :meth:`SliceLoads.differences`)
    and gathered into ``dx`` / ``dy`` / ``dz`` rows on first use (the unit chain's)."""

    _COLUMNS = {"dx": 2, "dy": 1, "dz": 0}

    def __missing__(self, key: str) -> np.ndarray:
        if key not in self._COLUMNS or "diff" not in self:
            raise KeyError(key)
        column = self["diff"][:, self._COLUMNS[key]].astype(np.int64)
        rows = self[key] = np.ascontiguousarray(column[self["routes"]])
        return rows


def read_plane(memory, kp: int, q: int) -> np.ndarray:
    """Voxel slice ``q`` along ``kp`` of ``memory`` (an :class:`SdramVolume`) as the
    ``(n_a, n_b)`` int64 plane its words deliver (stuck module and bank applied): what
    :meth:`SdramVolume.read_slice` hands the de-skew network, in voxel order, with the
    same counters (words read per module, the skew check)."""
    axes = [ax for ax in range(3) if ax != kp]
    n_a, n_b = memory.shape[axes[0]], memory.shape[axes[1]]
    cfg = memory.memory
    if cfg.skew not in ("miniblock", "block"):
        raise ValueError(f"the SDRAM front end reads mini-blocks: skew {cfg.skew!r} unsupported")
    stuck = np.array(
        [
            *(memory.stuck_module or (-1, 0)),
            *(memory.stuck_bank or (-1, -1, 0)),
        ],
        dtype=np.int64,
    )
    plane = np.empty((n_a, n_b), dtype=np.int64)
    reads = np.zeros(memory.M, dtype=np.int64)
    _read_plane(
        memory.words, kp, q, memory.n, memory.K, cfg.sdram.columns,
        cfg.skew == "block", stuck, plane, reads,
    )  # fmt: skip
    conflicts = memory._conflicts(kp, q)
    memory.counters.add("memory.conflicts", conflicts)
    if conflicts:
        raise AssertionError(f"skew violated: {conflicts} mini-block reads of slice {q}")
    memory.reads += reads
    return plane


@numba.njit(nogil=True, cache=True)
def _log2(v):
    """``log2(v)`` when ``v`` is a power of two, else -1."""
    if v <= 0 or (v & (v - 1)) != 0:
        return -1
    k = 0
    while (1 << k) < v:
        k += 1
    return k


@numba.njit(nogil=True, cache=True)
def _read_plane(words, kp, q, n, K, columns, block, stuck, plane, reads):
    """``plane[a, b]``: the word of voxel ``(a, b)`` of slice ``q`` (``vp500_miniblock``'s
    or ``block_miniblock``'s module, bank and address, the same formulas); ``stuck``: the
    stuck module and its value, the stuck bank's module, bank and value (-1: none)."""
    M = words.shape[0]
    mk = M * K
    lm, lmk = _log2(M), _log2(mk)
    shifts = lm >= 0 and lmk >= 0 and _log2(K) >= 0
    nb = (n + 1) // 2
    pitch = -(-nb // mk) * mk
    if block:
        nb = n // 2
        pitch = -(-nb // M) * M
        per_bank = -(-((8 * nb * nb * pitch) // M) // K)
        per_bank = -(-per_bank // columns) * columns
    n_a, n_b = plane.shape
    for a in range(n_a):
        for b in range(n_b):
            if kp == 0:
                z, y, x = q, a, b
            elif kp == 1:
                z, y, x = a, q, b
            else:
                z, y, x = a, b, q
            bx, by, bz = x >> 1, y >> 1, z >> 1
            s = bx + by + bz
            o = ((z & 1) << 2) | ((y & 1) << 1) | (x & 1)
            lb = (bz * nb + by) * pitch + bx
            if block:
                module = s % M
                linear = 8 * (lb // M) + o
                bank, address = linear // per_bank, linear % per_bank
            elif shifts:  # M and K powers of two: the same quotients, shifted
                module = s & (M - 1)
                bank = (s >> lm) & (K - 1)
                address = ((lb >> lmk) << 3) | o
            else:
                module = s % M
                bank = (s // M) % K
                address = ((lb // mk) << 3) | o
            v = np.int64(words[module, bank, address])
            if module == stuck[0]:
                v = stuck[1]
            if module == stuck[2] and bank == stuck[3]:
                v = stuck[4]
            plane[a, b] = v
            reads[module] += 1


@numba.njit(nogil=True, cache=True)
def _value_rows(plane, routes, shift, rows, voxels, pw, want, lut_shift, entries, lo, hi):
    """Each cell's four corners (``plane[number - 1]`` or 0) shifted left by ``shift``;
    ``voxels``: corner 0 of the slice's own cells (rows and columns from 2); with
    ``want``, ``lo`` / ``hi``: the LUT entries of the smallest and largest corner."""
    for c in range(routes.shape[0]):
        low = np.int64(0)
        high = np.int64(0)
        for k in range(4):
            i = routes[c, k]
            v = np.int64(0) if i == 0 else np.int64(plane[i - 1])
            v = v << shift
            rows[c, k] = v
            if k == 0 or v < low:
                low = v
            if k == 0 or v > high:
                high = v
        if want:
            lo[c] = classify_unit.lut_index_raw(low, lut_shift, entries)
            hi[c] = classify_unit.lut_index_raw(high, lut_shift, entries)
    n_a, n_b = voxels.shape
    for a in range(n_a):
        for b in range(n_b):
            voxels[a, b] = rows[(a + 2) * pw + b + 2, 0] >> shift


@numba.njit(nogil=True, cache=True, inline="always")
def _central(v, a, b, axis):
    """The in-slice central difference of ``v`` at ``(a, b)`` along ``axis`` (0: rows,
    1: columns); twice the one-sided difference at the edges, 0 across a single row."""
    n = v.shape[axis]
    if n < 2:
        return np.int64(0)
    i = a if axis == 0 else b
    lo = max(i - 1, 0) if i < n - 1 else n - 2
    hi = min(i + 1, n - 1) if i > 0 else 1
    scale = 2 if (i == 0 or i == n - 1) else 1
    if axis == 0:
        return scale * (v[hi, b] - v[lo, b])
    return scale * (v[a, hi] - v[a, lo])


@numba.njit(nogil=True, cache=True)
def _voxel_differences(lo, hi, factor, cur, shift, kp, a_ax, b_ax, diff):
    """``diff``: row 0 zeros, row ``1 + a n_b + b`` the differences at voxel ``(a, b)``
    shifted left by ``shift``, in columns by volume axis: ``factor (hi - lo)`` at ``kp``,
    the in-slice central differences along the rows at ``a_ax`` and columns at ``b_ax``."""
    n_a, n_b = cur.shape
    diff[0, 0] = diff[0, 1] = diff[0, 2] = 0  # nothing arrives
    for a in range(n_a):
        for b in range(n_b):
            j = 1 + a * n_b + b
            diff[j, kp] = (factor * (hi[a, b] - lo[a, b])) << shift
            diff[j, a_ax] = _central(cur, a, b, 0) << shift
            diff[j, b_ax] = _central(cur, a, b, 1) << shift


@numba.njit(nogil=True, cache=True)
def visible(lo0, hi0, lo1, hi1, ca, cb, pw, next_visible, out):
    """:meth:`TrilinearSource.maybe_visible` of a step's samples (cells ``(ca, cb)``,
    planes of width ``pw``): False where every LUT entry between the smallest and the
    largest corner of the sample's cells in the two slices (``lo0 / hi0``, ``lo1 /
    hi1``: the same slice twice when one is read) has opacity 0."""
    for i in range(ca.shape[0]):
        c = (ca[i] + 2) * pw + cb[i] + 2
        if c < 0 or c >= lo0.shape[0]:
            raise IndexError("a sample's cell lies outside the delivered corner planes")
        lo = min(lo0[c], lo1[c])
        hi = max(hi0[c], hi1[c])
        out[i] = next_visible[lo] <= hi


# ------------------------------------------------------------------ the NumPy form


def load_numpy(m, q: int) -> CornerPlanes:
    """:meth:`SlabMachine._load` in NumPy: the de-skewed stream of each channel (the
    voxels, or their pre-classified colours) through the ring to the corner planes; the
    reference :class:`SliceLoads` is compared with, and the pre-classified frames' path."""
    be, S = m.be, m.dp.interp.sample_frac_bits
    stream = m.memory.read_slice(m.kp, q)
    payloads = {}
    if be.pre_classified:
        rgba = be.classified_voxels(stream)
        payloads.update((c, v.reshape(stream.shape)) for c, v in zip("rgba", rgba, strict=True))
    if m.need_value:
        payloads["value"] = stream
    corners = {k: m.datapath.corners(v, q) for k, v in payloads.items()}
    if "value" in corners:
        m._voxels[q] = corners["value"][0, 2 : 2 + m.n_a, 2 : 2 + m.n_b]
    planes = CornerPlanes()
    if m.skip_transparent:
        if be.pre_classified:
            planes["amax"] = corners["a"].max(axis=0).ravel()
        else:
            value = corners["value"] << S
            planes["lo"], planes["hi"] = (
                classify_unit.lut_index(x.ravel(), m.dp.voxel_bits, S, m.dp.classify)
                for x in (value.min(axis=0), value.max(axis=0))
            )
    planes.update((k, _cell_rows(v, S)) for k, v in corners.items())
    return planes


def differences_numpy(m, q: int) -> dict[str, np.ndarray]:
    """:meth:`SlabMachine._differences` in NumPy: the difference planes streamed through
    the de-skew order and the ring like a slice of voxels (the reference)."""
    S = m.dp.interp.sample_frac_bits
    cur = m._voxel_plane(q)
    n = m.n_kp
    diffs: list[np.ndarray] = [None, None, None]  # type: ignore[list-item]
    if n >= 2:
        if q == 0:
            dk = 2 * (m._voxel_plane(1) - cur)
        elif q == n - 1:
            dk = 2 * (cur - m._voxel_plane(n - 2))
        else:
            dk = m._voxel_plane(q + 1) - m._voxel_plane(q - 1)
    else:
        dk = np.zeros_like(cur)
    diffs[m.kp] = dk
    for ax, axis in ((m.a_ax, 0), (m.b_ax, 1)):
        d = np.zeros_like(cur)
        if cur.shape[axis] >= 2:
            v, dv = np.moveaxis(cur, axis, 0), np.moveaxis(d, axis, 0)
            dv[1:-1] = v[2:] - v[:-2]
            dv[0] = 2 * (v[1] - v[0])
            dv[-1] = 2 * (v[-1] - v[-2])
        diffs[ax] = d
    sched = m.memory.schedule(m.kp, q)
    b = np.where(sched.valid, sched.b, 0)
    idle = ~sched.valid
    out = {}
    for name, axis in (("dx", 2), ("dy", 1), ("dz", 0)):
        stream = diffs[axis][sched.a, b]
        stream[idle] = 0
        out[name] = _cell_rows(m.datapath.corners(stream, q), S)
    return out


def _cell_rows(corners: np.ndarray, shift: int) -> np.ndarray:
    """Corner planes ``(4, ...)`` as one row of four corners per cell, shifted left by
    ``shift`` (the samples' fraction bits): ``(corners << shift).reshape(4, -1).T``, made
    C-contiguous in one pass."""
    rows = np.empty((corners[0].size, 4), dtype=corners.dtype)
    np.left_shift(corners.reshape(4, -1).T, shift, out=rows)
    return rows
