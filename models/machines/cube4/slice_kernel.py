"""Cube-4's compiled composite stage: one step's samples from the delivered corner planes.

# Ref: architectures.md sections 1.1-1.4 and 9.1 (Cube-4's pipelines: bilinear samples on
#      voxel slices, central-difference gradients over three slices, classification,
#      shading, compositing); models/fused_stage.py (the shading and blending shared with
#      the functional rung, inlined here).

:class:`~models.machines.cube4.cycle.HardwareSource` hands the back end's composite stage
(:meth:`models.backend.Backend._composite`) the samples of one step as a chain of
vectorised unit calls: a gather of each sample cell's four corners from the planes the
slice datapath delivered, a bilinear, the LUT, the six neighbours of the central-difference
gradient (cells moved one voxel along the in-slice axes, the same cell on the slices ahead
and behind), then normals, Phong, opacity correction and the blend.  At 64^3 that is some
forty NumPy calls per step, and the calls, not the arithmetic, are most of a frame.  Here
one compiled loop does the same: it reads the same corner planes (so a fault injected in
the ring, the FIFOs or the memory reaches the samples exactly as in the chain), calls the
same ``*_raw`` unit functions, keeps the visible samples and hands them to the shading
and blending shared with the functional rung (:func:`models.fused_stage.shade_and_blend`).

**Scope.**  The functional kernel's (:func:`models.fused_stage.eligible`): post-classified
composite through one LUT, one shader, steps whose samples share a step length with an
opacity-correction ROM; anything else takes the chain.
``tests/models/test_cycle_fused.py`` checks that both give the same bits, cycles and
counters.
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
from models.units import classify as classify_unit
from models.units import interp as interp_unit

__all__ = ["SliceKernel"]

#: Where the kernel reads outside the corner planes (a geometry bug, never data): the
#: chain would raise an IndexError there; the kernel stops and says so.
_OUTSIDE = 2


def _make_kernel(stage_hash: str):
    """The kernel (generic in the formats: one compilation serves every width)."""

    def kernel(
        cur, ahead, behind, a0, pw, pa, pb, ca, wa, cb, wb, rays, factor, rgb12, alpha12,
        grad_p, ratio, gm_table, light, half, intensity, spec, maps, table, acc, ert_thr,
        alive, sat, config, cols, need_grad,
    ):  # fmt: skip
        if len(stage_hash) == 0:  # never: keeps the hash in the cache key
            return
        s_bits, w_bits, w_code, lut_shift, entries, f_bits, spec_entries, one, acc_code = config
        g_k, g_a, g_b = cols[0], cols[1], cols[2]  # gradient rows (x, y, z) of each axis
        rows = cur.shape[0]
        cut = factor.shape[0] > 0
        world, modulates = grad_p[GRAD_FLAGS[0]] != 0, grad_p[GRAD_FLAGS[1]] != 0
        gm_scale, gm_entries = grad_p[GRAD_FLAGS[2]], grad_p[GRAD_FLAGS[3]]
        n = pa.shape[0]
        rgba = np.empty((4, n), np.int64)
        vis_rays = np.empty(n, np.int64)
        g = np.empty((3, n), np.int64)
        m = 0
        # Each plane's first row is its band's first beam a0 (0: a whole slice); the
        # slices ahead and behind may hold other bands: their rows are shifted.
        shift_ahead, shift_behind = (a0[0] - a0[1]) * pw, (a0[0] - a0[2]) * pw
        for i in range(n):
            row = (ca[i] + 2 - a0[0]) * pw + cb[i] + 2
            if row < 0 or row >= rows:
                sat[_OUTSIDE] = 1
                return
            value = _corners(cur, row, wa[i], wb[i], w_bits, w_code)
            idx = classify_unit.lut_index_raw(value, lut_shift, entries)
            alpha = alpha12[idx]
            if cut:
                alpha = classify_unit.scale_alpha_raw(alpha, factor[i])
            if alpha <= 0:
                continue  # transparent: changes nothing (Backend._composite's `vis`)
            if need_grad:
                # HardwareSource.gradient: along the principal axis the same cell on the
                # slices ahead and behind; in the slice the cell of p + 1 and p - 1 (its
                # weight quantised from its own fraction), the other axis unchanged.
                r_ahead, r_behind = row + shift_ahead, row + shift_behind
                if min(r_ahead, r_behind) < 0 or max(r_ahead, r_behind) >= rows:
                    sat[_OUTSIDE] = 1
                    return
                g[g_k, m] = _corners(ahead, r_ahead, wa[i], wb[i], w_bits, w_code) - _corners(
                    behind, r_behind, wa[i], wb[i], w_bits, w_code
                )
                diff_a = np.int64(0)
                diff_b = np.int64(0)
                for sign in (1.0, -1.0):
                    c, w = slice_cell(pa[i] + sign, w_bits, w_code)
                    r = (c + 2 - a0[0]) * pw + cb[i] + 2
                    c, w2 = slice_cell(pb[i] + sign, w_bits, w_code)
                    r2 = row - cb[i] + c
                    if r < 0 or r >= rows or r2 < 0 or r2 >= rows:
                        sat[_OUTSIDE] = 1
                        return
                    s_a = _corners(cur, r, w, wb[i], w_bits, w_code)
                    s_b = _corners(cur, r2, wa[i], w2, w_bits, w_code)
                    diff_a = s_a if sign > 0 else diff_a - s_a
                    diff_b = s_b if sign > 0 else diff_b - s_b
                g[g_a, m], g[g_b, m] = diff_a, diff_b
                g[0, m], g[1, m], g[2, m], alpha = world_and_modulate(
                    g[0, m], g[1, m], g[2, m], alpha, world, modulates, ratio, gm_scale,
                    gm_entries, gm_table,
                )  # fmt: skip
            rgba[0, m], rgba[1, m], rgba[2, m] = rgb12[idx, 0], rgb12[idx, 1], rgb12[idx, 2]
            rgba[3, m] = alpha
            vis_rays[m] = rays[i]
            m += 1
        shade_and_blend(
            rgba, vis_rays, g, m, grad_p, light, half, intensity, spec, maps, table, acc,
            ert_thr, alive, sat, f_bits, spec_entries, one, acc_code,
        )  # fmt: skip

    return numba.njit(cache=True, nogil=True)(kernel)


@numba.njit(inline="always")
def _corners(plane, row, wa, wb, w_bits, w_code):
    """:func:`~models.units.interp.bilinear_raw` of the four promoted corners of cell
    ``row`` of an interleaved ``(cells, 4)`` corner plane (``HardwareSource._bilinear``)."""
    return np.int64(
        interp_unit.bilinear_raw(
            plane[row, 0], plane[row, 1], plane[row, 2], plane[row, 3], wa, wb, w_bits, w_code
        )
    )


@functools.cache
def _kernel():
    """The compiled kernel(s), made once per process on first use."""
    return _make_kernel(STAGE_HASH)


class SliceKernel(StageConstants):
    """The compiled composite stage of one Cube-4 frame (None from :meth:`for_backend`
    when the frame is out of its scope)."""

    @classmethod
    def for_backend(cls, backend, a_ax: int, b_ax: int, kp: int) -> SliceKernel | None:
        if not eligible(backend):
            return None
        return cls(backend, a_ax, b_ax, kp)

    def __init__(self, backend, a_ax: int, b_ax: int, kp: int) -> None:
        super().__init__(backend)
        self.kernel = _kernel()
        #: The gradient's rows (x, y, z = 0, 1, 2) of the principal, a and b axes.
        self.cols = np.array([2 - kp, 2 - a_ax, 2 - b_ax], dtype=np.int64)
        self.need_grad = bool(backend.need_grad)

    def run(self, src, step, factor, state, table: np.ndarray) -> None:
        """Composite ``step``'s samples (after masks), interpolated from the planes of
        ``src`` (a ``HardwareSource`` of that step), into ``state``."""
        m, q = src.m, src.q
        here = m.planes(q)
        slices = (here, here, here)  # the slices ahead and behind: read for gradients only
        if self.need_grad:
            slices = (here, m.planes(min(q + 1, m.n_kp - 1)), m.planes(max(q - 1, 0)))
        planes = tuple(p["value"] for p in slices)
        a0 = np.array([p["a0"] for p in slices], dtype=np.int64)
        (ca, wa, _), (cb, wb, _) = src._cells
        per_sample = (
            np.ascontiguousarray(src.pa, dtype=np.float64),
            np.ascontiguousarray(src.pb, dtype=np.float64),
            ca,
            wa,
            cb,
            wb,
            np.asarray(step.rays, dtype=np.int64),
        )

        def run_part(pa, pb, ca, wa, cb, wb, rays, factor, state, table):
            sat = np.zeros(3, dtype=np.int64)
            self.kernel(
                *planes, a0, m.plane_width, pa, pb, ca, wa, cb, wb, rays, factor,
                self.rgb12, self.alpha12, self.grad_p, self.ratio, self.gm_table, self.light,
                self.half, self.intensity, self.spec, self.maps, table, state.acc,
                self.ert_thr, state.alive, sat, self.config, self.cols, self.need_grad,
            )  # fmt: skip
            if sat[_OUTSIDE]:
                raise IndexError("a sample's cell lies outside the delivered corner planes")
            return sat

        self.run_parts(run_part, per_sample, factor, state, table)
