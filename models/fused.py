"""The functional rung's compiled composite stage: position to accumulator in a few loops.

# Ref: design.md section 3 (functional rung); architectures.md section 9.1 (interpolator,
#      classifier, gradient, shader and compositor units); docs/fidelity.md ("How the
#      functional rung simulates fast, exactly").

:meth:`models.backend.Backend._composite` runs the composite stage as a chain of
vectorised unit calls, each producing a temporary array per step part.  Here the same
chain is numba-compiled: one loop over the part's samples takes the cell and weights
(:func:`~models.units.interp.cell_weight`), the trilinear sample (two
:func:`~models.units.interp.bilinear_raw` and a :func:`~models.units.interp.lerp_raw` of
voxels promoted as read, :func:`~models.units.interp.promote_raw`), the LUT read
(:func:`~models.units.classify.lut_index_raw`) and, for the visible samples, the six
neighbours of the sample gradient or the three interpolated voxel differences and the
gradient-opacity modulation; then branch-free loops over the visible samples compute the
normals (:func:`~models.units.gradient.normal_float_raw`), each light's Phong terms
(:func:`~models.units.shade.light_terms_raw`) and the shaded colours
(:func:`~models.units.shade.shade_raw`); a last loop applies the opacity-correction table
and the front-to-back blend (:func:`~models.units.composite.ftb_weight_raw`).

**One source of truth.**  Every rounding, lerp, root, division and clamp of the
datapath is a ``*_raw`` function of its unit, the same function the unit's vectorised
API calls on NumPy arrays; numba compiles it for scalars (``register_jitable``).  What
the kernel adds is the order of the calls (the dataflow of ``Backend._composite`` and
``gradient.sample_differences``) and the overflow rule of ``composite.alpha`` and
``composite.acc`` (count a value outside ``[0, 1.0]``, clamp it: ``_saturate_unit``),
which the chain's bounds make unreachable here; ``tests/models/test_functional_fused.py``
checks that it gives the vectorised chain's bits on every supported configuration.
Integer scalars are int64; the vectorised chain's int32 lerps are exact
(:func:`~models.units.interp.promote`), so both compute the same integers.

**Settled rays.**  Front to back, a sample's blend weight ``w = round((1 - A) a)``
(:func:`~models.units.composite.ftb_weight_raw`) depends only on its ray's accumulated
opacity ``A`` and its corrected opacity ``a``, both known right after classification
when the gradient does not modulate the opacity.  Once ``(1 - A) a`` rounds to 0 (an
opaque ray whose opacity stalls below 1.0 in fixed point: VolumePro 500 has no early
termination), the colour and opacity increments are ``round(0 c) = 0`` in every
rounding mode and the accumulators, saturation counts and early-termination flags stay
as they were, so the kernel skips that sample's gradient, shading and blend: the same
bits, the work of a ray that has stopped changing (half the kernel's time on the
VolPack benchmark's MR frames).

**Shared weights.**  In shear-warp order every sample of a step lies on one voxel slice
at the same fractional position, so its trilinear sample is the same call for every ray
but the cell.  The kernel builds a *plane* per call (:func:`_plane`): those samples over
the bounding box of the step's cells, widened by one, each computed once, on a voxel
slice as rows of ``b`` lerps shared by two cells (:func:`_slice_plane`, vectorised).  A
sample at the step's cell along the principal axis and weights reads its value there,
and inside the volume four of its six gradient neighbours (the centre's weights, the
next cells: :func:`_inner`); the two on the neighbouring slices, and every sample whose
position rounds to other weights (edges, shear-image and ray orders), take the direct
call.  Same calls, same bits; ``tests/models/test_functional_fused.py`` compares each
plane entry with the direct call.

**Scope.**  Post-classified composite through one LUT, steps whose samples share one
``dt`` (parallel views) and frames with one shader (or none), Phong or reflectance maps
(:func:`~models.units.shade.cell_index_raw`), gradients from samples or voxels, any
crop, cut planes, modulation and early termination.  Anything else (pre-classification,
multi-LUT classification, embedded geometry, perspective steps, the elision check) takes
the vectorised
chain: :func:`eligible` and :meth:`CompositeKernel.table` say which.

The compiled code is cached on disk (``cache=True``).  numba keys a cached kernel by the
kernel's own source file and bytecode, not by the unit functions and the shared stage it
inlines (:mod:`models.fused_stage`: shading, blending, the per-frame constants), so the
key here also holds a hash of their source (:data:`STAGE_HASH`): editing a unit or the
stage recompiles the kernel instead of loading stale arithmetic.
"""

from __future__ import annotations

import numba
import numpy as np

from hwsim.core.threads import THREADS_ENV_VAR
from hwsim.numerics import round_shift_raw
from models.fused_layout import kernel_voxels
from models.fused_stage import (
    _BTF_UP,
    _FROM_VOXELS,
    _GM_ENTRIES,
    _GM_SCALE,
    _MODULATES,
    _NEED_GRAD,
    _WORLD,
    GRAD_FLAGS,
    STAGE_HASH,
    UNITS_HASH,
    StageConstants,
    eligible,
    shade_and_blend,
    world_and_modulate,
)
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit

__all__ = [
    "GRAD_FLAGS",
    "STAGE_HASH",
    "THREADS_ENV_VAR",
    "UNITS_HASH",
    "CompositeKernel",
    "StageConstants",
    "eligible",
    "shade_and_blend",
    "world_and_modulate",
]


def _make_kernel(stage_hash: str, constants: tuple[int, ...] | None):
    """The kernel, compiled for one configuration or for any.

    The configuration (``S``, interpolation weight bits and rounding, LUT index shift
    and entries, normal bits, specular-table entries, accumulator 1.0 and rounding) is
    the kernel's ``config`` argument.  With ``constants`` (that same tuple) the kernel
    takes it from its closure instead, which numba compiles as constants: shifts by a
    known amount and rounding branches resolved at compile time run about twice as fast
    (:func:`_kernel_for` does this for a machine's own formats only, so a sweep over
    widths compiles one generic kernel, not one per width).  numba's on-disk cache is
    keyed by bytecode and closure values: each specialised configuration, the generic
    kernel and each ``stage_hash`` have their own entries.
    """
    specialised = constants is not None
    fixed = constants if constants is not None else (0,) * 9

    def kernel(
        vox, dxyz, shape, strides, offsets, kp, zyx, rays, factor, rgb12, alpha12,
        grad_p, ratio, gm_table, light, half, intensity, spec, maps, table, acc, ert_thr, alive,
        sat, config,
    ):  # fmt: skip
        if len(stage_hash) == 0:  # never: keeps the hash in the cache key
            return
        s_bits, w_bits, w_code, lut_shift, entries, f_bits, spec_entries, one, acc_code = (
            fixed if specialised else config
        )
        hi = (shape[0] - 1.0, shape[1] - 1.0, shape[2] - 1.0)
        st_z, st_y, st_x = strides[0], strides[1], strides[2]
        o1, o2, o3, o4 = offsets[1], offsets[2], offsets[3], offsets[4]
        cut = factor.shape[0] > 0
        world, modulates = grad_p[_WORLD] != 0, grad_p[_MODULATES] != 0
        gm_scale, gm_entries = grad_p[_GM_SCALE], grad_p[_GM_ENTRIES]
        n = zyx.shape[0]
        # Every sample's cell (rows z, y, x) and raw weights (rows 3-5), then the plane
        # of the step's shared cell along kp and weights (see _plane).
        cw = np.empty((6, n), np.int64)
        for i in range(n):
            for a in range(3):
                c, q = interp_unit.cell_weight(zyx[i, a], hi[a], w_bits, w_code)
                cw[a, i], cw[3 + a, i] = np.int64(c), np.int64(q)
        plane, key, box = _plane(vox, strides, offsets, shape, kp, cw, s_bits, w_bits, w_code)
        a_ax, b_ax, a_lo, b_lo, pw = box[0], box[1], box[2], box[3], box[4]
        cell = np.empty(3, np.int64)  # the centre's cell along z, y, x
        w = np.empty(3, np.int64)  # its raw weights
        # Pass 1, per sample: value, classification, gradient; the visible samples are
        # kept in these arrays (colour, opacity, ray, gradient x y z).
        rgba = np.empty((4, n), np.int64)
        vis_rays = np.empty(n, np.int64)
        g = np.empty((3, n), np.int64)
        # Front to back, opacity not modulated by the gradient: a sample's blend weight is
        # known before its gradient.
        settled = grad_p[_BTF_UP] < 0 and grad_p[_MODULATES] == 0
        m = 0
        for i in range(n):
            for a in range(3):
                cell[a], w[a] = cw[a, i], cw[3 + a, i]
            base = cell[0] * st_z + cell[1] * st_y + cell[2] * st_x
            on_plane = (
                pw > 0
                and cell[kp] == key[0]
                and w[0] == key[1]
                and w[1] == key[2]
                and w[2] == key[3]
            )
            if on_plane:  # the plane holds this sample: the same call, made once
                at = (cell[a_ax] - a_lo) * pw + cell[b_ax] - b_lo
                value = plane[at]
            else:
                value = _trilinear(
                    vox, base, o1, o2, o3, o4, w[0], w[1], w[2], s_bits, w_bits, w_code
                )
            idx = classify_unit.lut_index_raw(value, lut_shift, entries)
            alpha = alpha12[idx]
            if cut:
                alpha = classify_unit.scale_alpha_raw(alpha, factor[i])
            if alpha <= 0:
                continue  # transparent: changes nothing (Backend._composite's `vis`)
            if settled and alpha <= 4096:
                # A sample whose blend weight rounds to 0 (its ray's opacity has settled)
                # adds exactly nothing: no gradient, shading or blend (see Settled rays).
                ray = rays[i]
                if composite_unit.ftb_weight_raw(acc[ray, 3], table[alpha], one, acc_code) == 0:
                    if ert_thr >= 0:
                        alive[ray] = acc[ray, 3] < ert_thr  # what the blend would set
                    sat[2] += 1  # counted for the tests
                    continue
            if grad_p[_NEED_GRAD]:
                if grad_p[_FROM_VOXELS]:
                    for c3 in range(3):  # dxyz rows: x, y, z differences
                        g[c3, m] = _trilinear(
                            dxyz[c3], base, o1, o2, o3, o4, w[0], w[1], w[2], s_bits, w_bits, w_code
                        )
                elif (
                    _inner(zyx[i, 0], hi[0])
                    and _inner(zyx[i, 1], hi[1])
                    and _inner(zyx[i, 2], hi[2])
                ):
                    # Inside the volume, p +- 1 along every axis has the centre's weights
                    # and the next cell (see _inner): the six samples without cell_weight,
                    # the four in the plane's slice read from it.
                    for a in range(3):
                        if on_plane and a != kp:
                            step = pw if a == a_ax else 1
                            g[2 - a, m] = plane[at + step] - plane[at - step]
                            continue
                        ahead = _trilinear(
                            vox, base + strides[a], o1, o2, o3, o4, w[0], w[1], w[2],
                            s_bits, w_bits, w_code,
                        )  # fmt: skip
                        behind = _trilinear(
                            vox, base - strides[a], o1, o2, o3, o4, w[0], w[1], w[2],
                            s_bits, w_bits, w_code,
                        )  # fmt: skip
                        g[2 - a, m] = ahead - behind
                else:
                    # s(p + e) - s(p - e) per axis: the centre's cell and weights except
                    # along the moved axis (gradient.sample_differences).
                    for a in range(3):
                        ahead = np.int64(0)
                        for step in (1.0, -1.0):
                            c, q = interp_unit.cell_weight(zyx[i, a] + step, hi[a], w_bits, w_code)
                            nb = base + (np.int64(c) - cell[a]) * strides[a]
                            wz = np.int64(q) if a == 0 else w[0]
                            wy = np.int64(q) if a == 1 else w[1]
                            wx = np.int64(q) if a == 2 else w[2]
                            s = _trilinear(
                                vox, nb, o1, o2, o3, o4, wz, wy, wx, s_bits, w_bits, w_code
                            )
                            if step > 0:
                                ahead = s
                            else:
                                g[2 - a, m] = ahead - s
                # world_and_modulate's steps, written out: as a call they cost this
                # loop 4 % (measured on a 128^3 VolumePro 500 frame).
                if world:
                    for c3 in range(3):
                        g[c3, m] = round_shift_raw(g[c3, m] * ratio[c3], 12, 1)
                if modulates:
                    gx, gy, gz = g[0, m], g[1, m], g[2, m]
                    mag = gradient_unit.isqrt_raw(gx * gx + gy * gy + gz * gz)
                    gi = classify_unit.gm_index_raw(mag, gm_scale, gm_entries)
                    alpha = classify_unit.scale_alpha_raw(alpha, gm_table[gi])
            rgba[0, m], rgba[1, m], rgba[2, m] = rgb12[idx, 0], rgb12[idx, 1], rgb12[idx, 2]
            rgba[3, m] = alpha
            vis_rays[m] = rays[i]
            m += 1
        shade_and_blend(
            rgba, vis_rays, g, m, grad_p, light, half, intensity, spec, maps, table, acc,
            ert_thr, alive, sat, f_bits, spec_entries, one, acc_code,
        )  # fmt: skip

    return numba.njit(cache=True, nogil=True)(kernel)


#: Samples sharing a step's key from which a kernel call builds the plane, and the most
#: cells it computes per such sample (a sparse step's bounding box costs more than it
#: saves).
_PLANE_MIN, _PLANE_CELLS = 16, 4


@numba.njit(inline="always")
def _plane(vox, strides, offsets, shape, kp, cw, s_bits, w_bits, w_code):
    """The trilinear samples at the middle sample's cell along axis ``kp`` and raw
    weights (``key``: that cell, then the weights z, y, x) over the bounding box of the
    cells of the samples that share them, widened by one cell along the two other axes
    ``a`` and ``b`` (``box``: ``a``, ``b``, the box's first cells, its width; width 0
    when there is no plane).

    Shear-warp's regularity: a slice step's samples share one set of weights, so their
    values and the in-slice gradient neighbours (the centre's weights, the next cells:
    :func:`_inner`) are these entries, each computed by the same :func:`_trilinear`
    call as before, once per cell instead of once per use.  A sample whose cell along
    ``kp`` or weights differ (a rounding of its position, a clamp at the volume's
    edge, another plan kind) takes the direct call."""
    key = np.zeros(4, np.int64)
    box = np.zeros(5, np.int64)
    n = cw.shape[1]
    if kp < 0 or n < _PLANE_MIN:
        return np.empty(0, np.int64), key, box
    a_ax, b_ax = (1, 2) if kp == 0 else ((0, 2) if kp == 1 else (0, 1))
    mid = n // 2  # the first sample may sit on the volume's edge (clamped)
    key[0], key[1], key[2], key[3] = cw[kp, mid], cw[3, mid], cw[4, mid], cw[5, mid]
    a_lo, a_hi, b_lo, b_hi = shape[a_ax], -1, shape[b_ax], -1
    shared = 0
    for i in range(n):
        if cw[kp, i] == key[0] and cw[3, i] == key[1] and cw[4, i] == key[2]:
            if cw[5, i] == key[3]:
                shared += 1
                a_lo, a_hi = min(a_lo, cw[a_ax, i]), max(a_hi, cw[a_ax, i])
                b_lo, b_hi = min(b_lo, cw[b_ax, i]), max(b_hi, cw[b_ax, i])
    a_lo, b_lo = max(a_lo - 1, 0), max(b_lo - 1, 0)
    # Cells run to the last but one voxel (interp.cell_weight), 0 on an axis of one.
    a_hi = min(a_hi + 1, max(shape[a_ax] - 2, 0))
    b_hi = min(b_hi + 1, max(shape[b_ax] - 2, 0))
    pw = b_hi - b_lo + 1
    cells = (a_hi - a_lo + 1) * pw
    if shared < _PLANE_MIN or cells > _PLANE_CELLS * shared:
        return np.empty(0, np.int64), key, box
    box[0], box[1], box[2], box[3], box[4] = a_ax, b_ax, a_lo, b_lo, pw
    plane = np.empty(cells, np.int64)
    st_a, st_b = strides[a_ax], strides[b_ax]
    if key[1 + kp] == 0 and st_b == 1 and shape[a_ax] > 1 and shape[b_ax] > 1:
        _slice_plane(
            vox, key[0] * strides[kp] + b_lo, st_a, a_lo, a_hi, pw, key[1 + a_ax],
            key[1 + b_ax], plane, s_bits, w_bits, w_code,
        )  # fmt: skip
        return plane, key, box
    o1, o2, o3, o4 = offsets[1], offsets[2], offsets[3], offsets[4]
    wz, wy, wx = key[1], key[2], key[3]
    for ia in range(a_lo, a_hi + 1):
        row = key[0] * strides[kp] + ia * st_a
        out = (ia - a_lo) * pw - b_lo
        for ib in range(b_lo, b_hi + 1):
            plane[out + ib] = _trilinear(
                vox, row + ib * st_b, o1, o2, o3, o4, wz, wy, wx, s_bits, w_bits, w_code
            )
    return plane, key, box


@numba.njit(inline="always")
def _slice_plane(vox, first, st_a, a_lo, a_hi, pw, wa, wb, plane, s_bits, w_bits, w_code):
    """:func:`_plane`'s entries for samples on a voxel slice (weight 0 along ``kp``),
    the slice's ``b`` axis contiguous: :func:`_trilinear` of such a sample is
    :func:`~models.units.interp.bilinear_raw` of the slice's four corners (lerps along
    ``b``, then ``a``; a lerp of weight 0 returns its first operand exactly, so
    ``_trilinear``'s skipped lerps change nothing), here with each row's ``b`` lerps
    computed once for the two cells that read them.  ``first``: the voxel at the box's
    first ``a`` row and ``b`` cell."""
    above = np.empty(pw, np.int64)
    below = np.empty(pw, np.int64)
    for ia in range(a_lo, a_hi + 2):
        src = first + ia * st_a
        for ib in range(pw):
            below[ib] = interp_unit.lerp_raw(
                interp_unit.promote_raw(np.int64(vox[src + ib]), s_bits),
                interp_unit.promote_raw(np.int64(vox[src + ib + 1]), s_bits),
                wb,
                w_bits,
                w_code,
            )
        if ia > a_lo:
            out = (ia - 1 - a_lo) * pw
            for ib in range(pw):
                plane[out + ib] = interp_unit.lerp_raw(above[ib], below[ib], wa, w_bits, w_code)
        above, below = below, above


@numba.njit(inline="always")
def _inner(p, hi):
    """Whether ``interp.cell_weight`` gives ``p + 1`` and ``p - 1`` the cells next to
    ``p``'s and ``p``'s own weight, so that a gradient neighbour is the centre's sample
    moved by one cell.

    With ``1 <= p`` and ``p + 1 < hi`` no clamp applies to ``p`` or ``p +- 1``; ``p - 1``
    is exact (a multiple of ``p``'s ulp below ``p``), and ``p + 1`` is exact when
    ``(p + 1) - 1`` gives ``p`` back (rounded, it would be off by half an ulp of
    ``p + 1``, which the subtraction keeps).  Then ``floor(p +- 1) = floor(p) +- 1`` and
    the fractions ``(p +- 1) - (floor(p) +- 1)`` are the exact value ``p - floor(p)``
    (representable, so the subtraction returns it), quantised alike."""
    return p >= 1.0 and p + 1.0 < hi and (p + 1.0) - 1.0 == p


@numba.njit(inline="always")
def _trilinear(vox, base, o1, o2, o3, o4, wz, wy, wx, s_bits, w_bits, w_code):
    """The trilinear sample of cell ``base`` of the raw voxels ``vox``: each corner
    promoted as read (:func:`~models.units.interp.promote_raw`), then
    :func:`~models.units.interp.bilinear_raw` on the near slice, on the far slice and a
    z :func:`~models.units.interp.lerp_raw` -- ``interp.lerp_corners``' order (x, y, z).

    A lerp of weight 0 returns its first operand exactly (``interp.lerp_plan``), so an
    axis whose weight is 0 (the principal axis of a sample on a voxel slice) is not
    lerped and its far corners are not read: the remaining x, y or x, z or y, z lerps
    are one bilinear in the same order."""
    if wz == 0:
        return _bilinear(vox, base, o1, o2, wy, wx, s_bits, w_bits, w_code)
    if wy == 0:  # x lerps on the near and far slices, then z
        return _bilinear(vox, base, o1, o4, wz, wx, s_bits, w_bits, w_code)
    if wx == 0:  # y lerps on the near and far slices, then z
        return _bilinear(vox, base, o2, o4, wz, wy, s_bits, w_bits, w_code)
    near = _bilinear(vox, base, o1, o2, wy, wx, s_bits, w_bits, w_code)
    far = _bilinear(vox, base + o4, o1, o2, wy, wx, s_bits, w_bits, w_code)
    return np.int64(interp_unit.lerp_raw(near, far, wz, w_bits, w_code))


@numba.njit(inline="always")
def _bilinear(vox, base, ob, oa, wa, wb, s_bits, w_bits, w_code):
    """:func:`~models.units.interp.bilinear_raw` of the corners ``base``, ``+ ob``,
    ``+ oa`` and ``+ oa + ob`` (lerps along ``b`` first, then ``a``)."""
    row = base + oa
    return np.int64(
        interp_unit.bilinear_raw(
            interp_unit.promote_raw(np.int64(vox[base]), s_bits),
            interp_unit.promote_raw(np.int64(vox[base + ob]), s_bits),
            interp_unit.promote_raw(np.int64(vox[row]), s_bits),
            interp_unit.promote_raw(np.int64(vox[row + ob]), s_bits),
            wa,
            wb,
            w_bits,
            w_code,
        )
    )


#: Compiled kernels of this process, by configuration.
_KERNELS: dict[tuple[int, ...] | None, object] = {}


def _kernel_for(config: tuple[int, ...] | None):
    """The kernel specialised for ``config``, or the generic one for None."""
    kernel = _KERNELS.get(config)
    if kernel is None:
        kernel = _KERNELS[config] = _make_kernel(STAGE_HASH, config)
    return kernel


class CompositeKernel(StageConstants):
    """The functional rung's kernel for one back end: the stage constants and the
    volume's voxels laid out for it."""

    def __init__(self, backend, voxel_diffs: bool) -> None:
        """``voxel_diffs``: the gradient comes from voxels (the kernel then reads the
        voxel differences, ``gradient.voxel_differences``)."""
        super().__init__(backend)
        self.vox, self.shape, self.strides, self.offsets, self.dxyz = kernel_voxels(
            backend, voxel_diffs
        )
        axis = backend.plan.principal_axis
        #: The axis of the kernel's planes (:func:`_plane`): the plan's principal axis,
        #: -1 for none.
        self.kp = -1 if axis is None else int(axis)
        self.kernel = _kernel_for(self.config if self.own_formats else None)

    def run(self, step, factor, state, table: np.ndarray) -> None:
        """Composite the samples of ``step`` (after masks) into ``state``, with the
        opacity-correction ROM ``table`` (:meth:`table`), on the frame's threads
        (:meth:`run_parts`)."""
        zyx = np.ascontiguousarray(step.zyx, dtype=np.float64)
        rays = np.asarray(step.rays, dtype=np.int64)
        self.run_parts(self.run_part, (zyx, rays), factor, state, table)

    def run_part(self, zyx, rays, factor, state, table) -> np.ndarray:
        """One run of samples through the kernel; returns its saturation counts
        (``composite.alpha``, ``composite.acc``) and the settled samples it skipped."""
        sat = np.zeros(3, dtype=np.int64)
        self.kernel(
            self.vox,
            self.dxyz,
            self.shape,
            self.strides,
            self.offsets,
            self.kp,
            zyx,
            rays,
            factor,
            self.rgb12,
            self.alpha12,
            self.grad_p,
            self.ratio,
            self.gm_table,
            self.light,
            self.half,
            self.intensity,
            self.spec,
            self.maps,
            table,
            state.acc,
            self.ert_thr,
            state.alive,
            sat,
            self.config,
        )
        return sat
