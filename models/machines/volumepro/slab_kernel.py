"""The VolumePro family's compiled composite stage: one step's trilinear samples from the
corner planes the ring delivered.

# Ref: architectures.md sections 3 and 9.1 (VolumePro 500 z-supersampling: trilinear
#      samples between voxel slices; gradients from samples or, VolumePro 1000, from
#      voxels then interpolated); models/machines/volumepro/trilinear.py (the chain this
#      replaces, lerp for lerp); models/fused_stage.py (the shading and blending it inlines).

:class:`~models.machines.volumepro.trilinear.TrilinearSource` hands the back end's
composite stage a chain of vectorised unit calls per step. Here two compiled loops do the
same, in two passes so that the voxel slices the SDRAM delivers are asked for exactly when
the chain asks for them (a slice's first use reads it from memory, with its counters):

1. every sample's value from the slices of its step's principal-axis taps, the LUT and
   the cut-plane factor; the visible samples are kept (none: the step ends, as the
   chain's does, without touching the gradient's slices);
2. for the visible samples, the gradient (the voxel differences' planes at the same
   taps, or the samples one voxel away: the slices of the taps at ``p +- 1`` along the
   principal axis, the cells at ``p +- 1`` in the slice), world units and modulation,
   then :func:`models.fused_stage.shade_and_blend`.

Each trilinear sample lerps its eight corners x, then y, then z (``_tri``'s order), or,
when the principal-axis weight is 0 or 1, bilinears the one slice it selects: the same
integers.  Scope: :func:`models.fused_stage.eligible`, steps with an opacity-correction ROM.
``tests/models/test_cycle_fused.py`` checks image, cycles and counters against the chain.
"""

from __future__ import annotations

import functools

import numba
import numpy as np

from models.fused_stage import (
    GRAD_FLAGS,
    STAGE_HASH,
    StageConstants,
    eligible,
    shade_and_blend,
    slice_cell,
    world_and_modulate,
)
from models.machines.volumepro.threads import FinishBehind
from models.units import classify as classify_unit
from models.units import interp as interp_unit

__all__ = ["SlabKernel"]

_OUTSIDE = 2  # sat[2]: a cell outside the delivered planes (a geometry bug, never data)


@numba.njit(inline="always")
def _tri(p0, p1, row, wk, wa, wb, kp, w_bits, w_code):
    """The trilinear sample of cell ``row``: ``p0`` / ``p1`` the near and far slices'
    interleaved corner planes (corner ``2 da + db``), ``wk`` the principal-axis weight
    (0: ``p0`` alone, a bilinear), ``kp`` the principal axis (:func:`_tri8`)."""
    return _tri8(
        p0[row, 0], p0[row, 1], p0[row, 2], p0[row, 3],
        p1[row, 0], p1[row, 1], p1[row, 2], p1[row, 3], wk, wa, wb, kp, w_bits, w_code,
    )  # fmt: skip


@numba.njit(inline="always")
def _tri8(n0, n1, n2, n3, f0, f1, f2, f3, wk, wa, wb, kp, w_bits, w_code):
    """The trilinear sample of one cell's near (``n*``) and far (``f*``) corners (corner
    ``2 da + db``); ``wk`` 0: the near corners alone, a bilinear.  The eight corners are
    lerped x, then y, then z (``TrilinearSource._tri``), written out per principal axis;
    the voxel differences' corners are read through the ring's routes (``finish``)."""
    if wk == 0:
        return np.int64(interp_unit.bilinear_raw(n0, n1, n2, n3, wa, wb, w_bits, w_code))
    lerp = interp_unit.lerp_raw
    if kp == 0:  # a = y, b = x: a bilinear on each slice, then z
        near = interp_unit.bilinear_raw(n0, n1, n2, n3, wa, wb, w_bits, w_code)
        far = interp_unit.bilinear_raw(f0, f1, f2, f3, wa, wb, w_bits, w_code)
        return np.int64(lerp(near, far, wk, w_bits, w_code))
    if kp == 1:  # a = z, b = x: x along b, y across the slices, z along a
        y0 = lerp(
            lerp(n0, n1, wb, w_bits, w_code), lerp(f0, f1, wb, w_bits, w_code), wk, w_bits, w_code
        )
        y1 = lerp(
            lerp(n2, n3, wb, w_bits, w_code), lerp(f2, f3, wb, w_bits, w_code), wk, w_bits, w_code
        )
        return np.int64(lerp(y0, y1, wa, w_bits, w_code))
    # kp == 2: a = z, b = y: x across the slices, y along b, z along a
    y0 = lerp(
        lerp(n0, f0, wk, w_bits, w_code), lerp(n1, f1, wk, w_bits, w_code), wb, w_bits, w_code
    )
    y1 = lerp(
        lerp(n2, f2, wk, w_bits, w_code), lerp(n3, f3, wk, w_bits, w_code), wb, w_bits, w_code
    )
    return np.int64(lerp(y0, y1, wa, w_bits, w_code))


def _make_kernels(stage_hash: str, constants: tuple[int, ...] | None):
    """The two passes, compiled for one configuration (``constants``: the
    :class:`StageConstants` ``config`` tuple, taken from the closure, which numba
    compiles as constants: the lerps' shifts and rounding branches resolved, as
    :func:`models.fused._make_kernel` does) or for any (None: ``config`` read at run
    time).  numba's on-disk cache keys each by its closure values."""
    specialised = constants is not None
    fixed = constants if constants is not None else (0,) * 9

    def values(v0, v1, wk, pw, ca, wa, cb, wb, factor, alpha12, config, axes, keep, idx_out,
               alpha_out, sat):  # fmt: skip
        """Pass 1: value, LUT and factor of every sample; the visible ones kept."""
        if len(stage_hash) == 0:  # never: keeps the hash in the cache key
            return 0
        cfg = fixed if specialised else config
        w_bits, w_code, lut_shift, entries = cfg[1], cfg[2], cfg[3], cfg[4]
        rows = v0.shape[0]
        cut = factor.shape[0] > 0
        m = 0
        for i in range(ca.shape[0]):
            row = (ca[i] + 2) * pw + cb[i] + 2
            if row < 0 or row >= rows:
                sat[_OUTSIDE] = 1
                return m
            value = _tri(v0, v1, row, wk, wa[i], wb[i], axes[0], w_bits, w_code)
            idx = classify_unit.lut_index_raw(value, lut_shift, entries)
            alpha = alpha12[idx]
            if cut:
                alpha = classify_unit.scale_alpha_raw(alpha, factor[i])
            if alpha > 0:
                keep[m], idx_out[m], alpha_out[m] = i, idx, alpha
                m += 1
        return m

    def finish(
        keep, m, idx_in, alpha_in, diff0, diff1, routes0, routes1, gk, u0, u1, wu, d0, d1, wd,
        v0, v1, wk, pw, pa, pb,
        ca, wa, cb, wb, rays, voxel_grad, need_grad, rgb12, grad_p, ratio, gm_table, light,
        half, intensity, spec, maps, table, acc, ert_thr, alive, sat, config, axes,
    ):  # fmt: skip
        """Pass 2: gradients of the visible samples, shading and the blend.  ``diff*``,
        ``routes*``: the per-voxel differences (z, y, x) of the value's taps' slices and
        their cells' routes; ``u*, d*``: the value planes of the taps at ``p + 1`` and
        ``p - 1`` along the principal axis."""
        if len(stage_hash) == 0:
            return
        cfg = fixed if specialised else config
        w_bits, w_code = cfg[1], cfg[2]
        f_bits, spec_entries, one, acc_code = cfg[5], cfg[6], cfg[7], cfg[8]
        kp, a_ax, b_ax = axes[0], axes[1], axes[2]
        rows = v0.shape[0]
        world, modulates = grad_p[GRAD_FLAGS[0]] != 0, grad_p[GRAD_FLAGS[1]] != 0
        gm_scale, gm_entries = grad_p[GRAD_FLAGS[2]], grad_p[GRAD_FLAGS[3]]
        rgba = np.empty((4, m), np.int64)
        vis_rays = np.empty(m, np.int64)
        g = np.empty((3, m), np.int64)
        for j in range(m):
            i = keep[j]
            row = (ca[i] + 2) * pw + cb[i] + 2
            alpha = alpha_in[j]
            if need_grad:
                if voxel_grad:  # the interpolated x, y, z voxel differences
                    # The cell's corners: the voxels the routes name (0: nothing, zeros),
                    # read once for the three components; g[0] is x, column 2.
                    n0, n1, n2, n3 = (
                        routes0[row, 0],
                        routes0[row, 1],
                        routes0[row, 2],
                        routes0[row, 3],
                    )
                    f0, f1, f2, f3 = (
                        routes1[row, 0],
                        routes1[row, 1],
                        routes1[row, 2],
                        routes1[row, 3],
                    )
                    for col in range(3):
                        c = 2 - col
                        g[col, j] = _tri8(
                            np.int64(diff0[n0, c]), np.int64(diff0[n1, c]),
                            np.int64(diff0[n2, c]), np.int64(diff0[n3, c]),
                            np.int64(diff1[f0, c]), np.int64(diff1[f1, c]),
                            np.int64(diff1[f2, c]), np.int64(diff1[f3, c]),
                            gk, wa[i], wb[i], kp, w_bits, w_code,
                        )  # fmt: skip
                else:
                    ahead = _tri(u0, u1, row, wu, wa[i], wb[i], kp, w_bits, w_code)
                    behind = _tri(d0, d1, row, wd, wa[i], wb[i], kp, w_bits, w_code)
                    g[2 - kp, j] = ahead - behind
                    diff_a = np.int64(0)
                    diff_b = np.int64(0)
                    for sign in (1.0, -1.0):
                        c, w = slice_cell(pa[i] + sign, w_bits, w_code)
                        r = (c + 2) * pw + cb[i] + 2
                        c2, w2 = slice_cell(pb[i] + sign, w_bits, w_code)
                        r2 = row - cb[i] + c2
                        if r < 0 or r >= rows or r2 < 0 or r2 >= rows:
                            sat[_OUTSIDE] = 1
                            return
                        s_a = _tri(v0, v1, r, wk, w, wb[i], kp, w_bits, w_code)
                        s_b = _tri(v0, v1, r2, wk, wa[i], w2, kp, w_bits, w_code)
                        diff_a = s_a if sign > 0 else diff_a - s_a
                        diff_b = s_b if sign > 0 else diff_b - s_b
                    g[2 - a_ax, j], g[2 - b_ax, j] = diff_a, diff_b
                g[0, j], g[1, j], g[2, j], alpha = world_and_modulate(
                    g[0, j], g[1, j], g[2, j], alpha, world, modulates, ratio, gm_scale,
                    gm_entries, gm_table,
                )  # fmt: skip
            idx = idx_in[j]
            rgba[0, j], rgba[1, j], rgba[2, j] = rgb12[idx, 0], rgb12[idx, 1], rgb12[idx, 2]
            rgba[3, j] = alpha
            vis_rays[j] = rays[i]
        shade_and_blend(
            rgba, vis_rays, g, m, grad_p, light, half, intensity, spec, maps, table, acc,
            ert_thr, alive, sat, f_bits, spec_entries, one, acc_code,
        )  # fmt: skip

    jit = numba.njit(cache=True, nogil=True)
    return jit(values), jit(finish)


@functools.cache
def _kernels(constants: tuple[int, ...] | None = None):
    """The compiled passes for ``constants`` (None: the generic ones), made once per
    process on first use."""
    return _make_kernels(STAGE_HASH, constants)


class SlabKernel(StageConstants):
    """The compiled composite stage of one VolumePro-family frame."""

    @classmethod
    def for_backend(cls, backend, machine) -> SlabKernel | None:
        if not eligible(backend):
            return None
        return cls(backend, machine)

    def __init__(self, backend, machine) -> None:
        super().__init__(backend)
        # Specialised for the machine's own formats (a width sweep shares the generic).
        self.values, self.finish = _kernels(self.config if self.own_formats else None)
        self.machine = machine
        self.axes = np.array([machine.kp, machine.a_ax, machine.b_ax], dtype=np.int64)
        self.need_grad = bool(backend.need_grad)
        self._no_factor = np.zeros(0, dtype=np.int64)
        self._no_diff = np.zeros((1, 3), dtype=machine.loads.diff_type)
        self._no_routes = np.zeros((1, 4), dtype=machine.loads.index_type)
        self._no_routes.setflags(write=False)  # typed as the routes (read-only, shared)
        #: Where the second pass runs: at once, or behind the data pass on a worker
        #: thread (the frame's :class:`~models.machines.volumepro.threads.FinishBehind`).
        self.behind = FinishBehind(1)

    def table(self, dt) -> np.ndarray | None:
        table = super().table(dt)
        if table is None:  # the unit chain blends this step: the passes behind first
            self.behind.join()
        return table

    def _taps(self, channel: str, taps) -> tuple[np.ndarray, np.ndarray, int]:
        """The planes a trilinear sample at ``taps = (i0, i1, w)`` reads, asked for as
        ``TrilinearSource._tri`` asks (one slice when the weight selects it)."""
        m = self.machine
        i0, i1, w = taps
        if w == 0 or w == m.weight_one:
            plane = m.planes(i0 if w == 0 else i1)[channel]
            return plane, plane, 0
        return m.planes(i0)[channel], m.planes(i1)[channel], w

    def run(self, src, step, factor, state, table: np.ndarray) -> None:
        m = self.machine
        factor = self._no_factor if factor is None else np.asarray(factor, dtype=np.int64)
        (ca, wa, _), (cb, wb, _) = src._cells
        n = ca.size
        taps = m.k_taps(src.pk)
        v0, v1, wk = self._taps("value", taps)
        keep = np.empty(n, np.int64)
        idx, alpha = np.empty(n, np.int64), np.empty(n, np.int64)
        sat = np.zeros(3, dtype=np.int64)
        k = self.values(v0, v1, wk, m.plane_width, ca, wa, cb, wb, factor, self.alpha12,
                        self.config, self.axes, keep, idx, alpha, sat)  # fmt: skip
        if sat[_OUTSIDE]:
            raise IndexError("a sample's cell lies outside the delivered corner planes")
        if k == 0:
            return  # nothing visible: the gradient's slices are not asked for
        grads = [self._no_diff] * 2 + [self._no_routes] * 2  # typed, unread unless used
        u0 = u1 = d0 = d1 = v0
        gk = wu = wd = 0
        voxel = m.voxel_gradients
        if self.need_grad:
            if voxel:  # the slices' per-voxel differences and routes (SliceLoads)
                diff0, diff1, gk = self._taps("diff", taps)
                routes0, routes1, _ = self._taps("routes", taps)
                grads = [diff0, diff1, routes0, routes1]
            else:
                pk = src.pk
                u0, u1, wu = self._taps("value", m.k_taps(pk + 1.0))
                d0, d1, wd = self._taps("value", m.k_taps(pk - 1.0))
        args = (
            keep, k, idx, alpha, *grads, gk, u0, u1, wu, d0, d1, wd, v0, v1, wk,
            m.plane_width, np.ascontiguousarray(src.pa, dtype=np.float64),
            np.ascontiguousarray(src.pb, dtype=np.float64), ca, wa, cb, wb,
            np.asarray(step.rays, dtype=np.int64), voxel, self.need_grad, self.rgb12,
            self.grad_p, self.ratio, self.gm_table, self.light, self.half, self.intensity,
            self.spec, self.maps, table, state.acc, self.ert_thr, state.alive, sat,
            self.config, self.axes,
        )  # fmt: skip
        self.behind.launch(self.finish, args, functools.partial(self._finished, sat))

    def _finished(self, sat: np.ndarray) -> None:
        """After a second pass, on the frame's thread: its checks and saturation counts."""
        if sat[_OUTSIDE]:
            raise IndexError("a sample's cell lies outside the delivered corner planes")
        self.count_saturations(sat)
