"""Trilinear samples across two voxel slices, from the corner planes the ring delivered.

# Ref: architectures.md sections 3 and 9.1 (VolumePro 500 z-supersampling: sample slices
#      between voxel slices, trilinear interpolation); models/units/interp.py (the lerps,
#      their order x, y, z, and rounding).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numba
import numpy as np

from hwsim.golden.positions import Step
from hwsim.numerics import ROUNDING_CODES
from models.backend import run_compiled
from models.fused_stage import STAGE_HASH, slice_cell
from models.machines.volumepro.slice_loads import visible
from models.units import interp as interp_unit

if TYPE_CHECKING:
    from models.machines.volumepro.cycle import SlabMachine

__all__ = ["TrilinearSource"]


class TrilinearSource:
    """Samples of one step, trilinear across the two voxel slices around the sample slice.

    In-slice cells and weights are Cube-4's (:meth:`Cube4Machine.cell`); the principal
    axis taps are the functional rung's (``i0 = min(floor(q), n - 2)``, weight quantised
    from ``q - i0``), and the eight corners are combined with ``models.units.interp.lerp``
    in its order (x, then y, then z), so every sample is the functional rung's bit for bit.
    """

    def __init__(self, machine: SlabMachine, step: Step) -> None:
        m = self.m = machine
        if not _compiled_cells(self, step.zyx):
            # Contiguous copies: every pass reads them (cells, slots, rule 6, the kernel).
            self.pa = np.ascontiguousarray(step.zyx[:, m.a_ax])
            self.pb = np.ascontiguousarray(step.zyx[:, m.b_ax])
            self.pk = np.ascontiguousarray(step.zyx[:, m.kp])
            self._cells = m.cell(self.pa), m.cell(self.pb)
        self.q = m.nearest_slice(self.pk)

    def subset(self, sel: np.ndarray) -> TrilinearSource:
        """The samples ``sel`` (indices or a mask) of this source."""
        out = object.__new__(TrilinearSource)
        out.m, out.q = self.m, self.q
        (ca, wa, fa), (cb, wb, fb) = self._cells
        arrays = (self.pa, self.pb, self.pk, fa, fb, ca, wa, cb, wb)
        sel = np.asarray(sel)
        floats = [np.empty(sel.size) for _ in range(5)]
        ints = [np.empty(sel.size, dtype=np.int64) for _ in range(4)]
        # One compiled gather of the nine arrays (the GIL released), not nine.
        if (
            sel.ndim == 1
            and sel.dtype == np.int64
            and _same_kinds(arrays)
            and _gather(sel, *arrays, *floats, *ints)
        ):
            out.pa, out.pb, out.pk, fa, fb = floats
            ca, wa, cb, wb = ints
            out._cells = (ca, wa, fa), (cb, wb, fb)
            return out
        out.pa, out.pb, out.pk = self.pa[sel], self.pb[sel], self.pk[sel]
        out._cells = tuple(tuple(x[sel] for x in cell) for cell in self._cells)
        return out

    def _tri(self, channel: str, cells_a, cells_b, ktaps) -> np.ndarray:
        m = self.m
        (ca, fa, _), (cb, fb, _) = cells_a, cells_b
        i0, i1, w = ktaps
        idx = (ca + 2) * m.plane_width + (cb + 2)
        if w == 0 or w == m.weight_one:
            # lerp(a, b, 0) = a and lerp(a, b, 1.0) = b exactly: one slice's bilinear.
            c = np.take(m.planes(i0 if w == 0 else i1)[channel], idx, axis=0)
            return interp_unit.bilinear(c[:, 0], c[:, 1], c[:, 2], c[:, 3], fa, fb, m.dp.interp)
        c0 = np.take(m.planes(i0)[channel], idx, axis=0)
        c1 = np.take(m.planes(i1)[channel], idx, axis=0)
        f = [None, None, None]
        f[m.kp], f[m.a_ax], f[m.b_ax] = w, fa, fb
        v = []
        for corner in range(8):
            d = ((corner >> 2) & 1, (corner >> 1) & 1, corner & 1)  # (z, y, x)
            src = c1 if d[m.kp] else c0
            v.append(src[:, 2 * d[m.a_ax] + d[m.b_ax]])
        cfg = m.dp.interp
        fz, fy, fx = f
        x = [interp_unit.lerp(v[c], v[c + 1], fx, cfg) for c in (0, 2, 4, 6)]
        y = [interp_unit.lerp(x[0], x[1], fy, cfg), interp_unit.lerp(x[2], x[3], fy, cfg)]
        return interp_unit.lerp(y[0], y[1], fz, cfg)

    def composite_fused(self, step: Step, factor: np.ndarray | None, state) -> bool:
        """Run the back end's composite stage on ``step`` in two compiled passes
        (:mod:`models.machines.volumepro.slab_kernel`) when the frame allows it; False:
        use the unit chain."""
        return run_compiled(self.m.kernel, step, factor, state, self)

    def maybe_visible(self) -> np.ndarray | None:
        """False where every voxel of a sample's two cells classifies to opacity 0."""
        m = self.m
        if not m.skip_transparent:
            return None
        (ca, _, _), (cb, _, _) = self._cells
        i0, i1, w = m.k_taps(self.pk)
        slices = [i0] if w == 0 else [i1] if w == m.weight_one else [i0, i1]
        if m.kernel is not None and not m.be.pre_classified:  # slice_loads.visible: compiled
            p0, p1 = m.planes(slices[0]), m.planes(slices[-1])
            out = np.empty(ca.size, dtype=bool)
            visible(p0["lo"], p0["hi"], p1["lo"], p1["hi"], ca, cb, m.plane_width,
                    m.next_visible, out)  # fmt: skip
            return out
        idx = (ca + 2) * m.plane_width + (cb + 2)
        if m.be.pre_classified:
            return np.logical_or.reduce([m.planes(s)["amax"][idx] > 0 for s in slices])
        lo = np.minimum.reduce([m.planes(s)["lo"][idx] for s in slices])
        hi = np.maximum.reduce([m.planes(s)["hi"][idx] for s in slices])
        return m.next_visible[lo] <= hi

    def value(self) -> np.ndarray:
        return self._tri("value", *self._cells, self.m.k_taps(self.pk))

    def channels(self) -> list[np.ndarray]:
        k = self.m.k_taps(self.pk)
        return [self._tri(c, *self._cells, k) for c in "rgba"]

    def gradient(self, sel: np.ndarray) -> np.ndarray:
        m = self.m
        cells_a, cells_b = (tuple(x[sel] for x in cell) for cell in self._cells)
        pk = self.pk[sel]
        k = m.k_taps(pk)
        g = np.empty((pk.size, 3), dtype=np.int64)
        if m.voxel_gradients:
            for col, ch in enumerate(("dx", "dy", "dz")):
                g[:, col] = self._tri(ch, cells_a, cells_b, k)
            return g
        g[:, 2 - m.kp] = self._tri("value", cells_a, cells_b, m.k_taps(pk + 1.0)) - self._tri(
            "value", cells_a, cells_b, m.k_taps(pk - 1.0)
        )
        pa, pb = self.pa[sel], self.pb[sel]
        up, down = m.cell(pa + 1.0, cells_a), m.cell(pa - 1.0, cells_a)
        g[:, 2 - m.a_ax] = self._tri("value", up, cells_b, k) - self._tri("value", down, cells_b, k)
        up, down = m.cell(pb + 1.0, cells_b), m.cell(pb - 1.0, cells_b)
        g[:, 2 - m.b_ax] = self._tri("value", cells_a, up, k) - self._tri("value", cells_a, down, k)
        return g


def _compiled_cells(source: TrilinearSource, zyx: np.ndarray) -> bool:
    """``source``'s positions ``pa``, ``pb``, ``pk`` (contiguous) and its two in-slice
    cells as :meth:`SliceOrderMachine.cell <models.machines.common.slice_order.
    SliceOrderMachine.cell>` gives them, in one compiled pass over ``zyx`` that releases
    the GIL (on the two-thread frame's steps thread, models/machines/volumepro/threads.py:
    one call, not three copies and two dozen NumPy passes); False (nothing set) where a
    position is not finite or a weight leaves its format, whose errors and saturation
    counts ``cell`` keeps."""
    m = source.m
    if zyx.dtype != np.float64 or zyx.ndim != 2 or zyx.shape[1] != 3:
        return False
    n, fmt = zyx.shape[0], m.dp.interp.weight
    pos = [np.empty(n) for _ in range(3)]
    cells = [np.empty(n, dtype=np.int64) for _ in range(4)]
    fracs = [np.empty(n) for _ in range(2)]
    ok = _cells_kernel()(
        zyx, m.a_ax, m.b_ax, m.kp, fmt.frac_bits, ROUNDING_CODES[fmt.rounding], fmt.raw_min,
        fmt.raw_max, *pos, *cells, *fracs,
    )  # fmt: skip
    if ok:
        source.pa, source.pb, source.pk = pos
        ca, wa, cb, wb = cells
        source._cells = (ca, wa, fracs[0]), (cb, wb, fracs[1])
    return ok


def _make_cells_kernel(stage_hash: str):
    def kernel(
        zyx, a_ax, b_ax, kp, w_bits, w_code, raw_min, raw_max, pa, pb, pk, ca, wa, cb, wb, fa, fb
    ):  # fmt: skip
        """Each row's axes into ``pa``, ``pb``, ``pk``; per in-slice axis its cell
        ``floor(p)`` (int64), the weight quantised from ``p - floor(p)`` (``slice_cell``,
        the compiled stages' geometry unit: ``FixedFormat.quantize``'s arithmetic) and that
        float fraction.  False at the first position not finite or weight outside
        ``raw_min .. raw_max``."""
        if len(stage_hash) == 0:  # never: keeps the hash in the cache key
            return False
        for i in range(zyx.shape[0]):
            x, y = zyx[i, a_ax], zyx[i, b_ax]
            if not (np.isfinite(x) and np.isfinite(y)):
                return False
            pa[i], pb[i], pk[i] = x, y, zyx[i, kp]
            c, w = slice_cell(x, w_bits, w_code)
            c2, w2 = slice_cell(y, w_bits, w_code)
            if w < raw_min or w > raw_max or w2 < raw_min or w2 > raw_max:
                return False
            ca[i], wa[i], fa[i] = c, w, x - np.floor(x)
            cb[i], wb[i], fb[i] = c2, w2, y - np.floor(y)
        return True

    return numba.njit(cache=True, nogil=True)(kernel)


@functools.cache
def _cells_kernel():
    """:func:`_compiled_cells`' kernel, made once per process on first use."""
    return _make_cells_kernel(STAGE_HASH)


def _same_kinds(arrays: tuple) -> bool:
    """Whether ``arrays`` are five float64 then four int64 1-D arrays of one length."""
    n = arrays[0].shape
    kinds = [np.float64] * 5 + [np.int64] * 4
    return all(x.dtype == k and x.shape == n for x, k in zip(arrays, kinds, strict=True))


@numba.njit(cache=True, nogil=True)
def _gather(sel, f0, f1, f2, f3, f4, i0, i1, i2, i3, g0, g1, g2, g3, g4, j0, j1, j2, j3):
    """``g* = f*[sel]``, ``j* = i*[sel]`` in one loop, as NumPy's gathers give them;
    False at an index out of range (NumPy's IndexError then)."""
    n = f0.size
    for k in range(sel.size):
        s = sel[k]
        if s < 0:
            s += n
        if s < 0 or s >= n:
            return False
        g0[k], g1[k], g2[k], g3[k], g4[k] = f0[s], f1[s], f2[s], f3[s], f4[s]
        j0[k], j1[k], j2[k], j3[k] = i0[s], i1[s], i2[s], i3[s]
    return True
