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
normals (:func:`~models.units.gradient.normal_raw`), each light's Phong terms
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

import weakref

import numba
import numpy as np

from hwsim.core.threads import THREADS_ENV_VAR
from hwsim.numerics import round_shift_raw
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
        vox, dxyz, shape, strides, offsets, zyx, rays, factor, rgb12, alpha12,
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
        cell = np.empty(3, np.int64)  # the centre's cell along z, y, x
        w = np.empty(3, np.int64)  # its raw weights
        # Pass 1, per sample: value, classification, gradient; the visible samples are
        # kept in these arrays (colour, opacity, ray, gradient x y z).
        n = zyx.shape[0]
        rgba = np.empty((4, n), np.int64)
        vis_rays = np.empty(n, np.int64)
        g = np.empty((3, n), np.int64)
        # Front to back, opacity not modulated by the gradient: a sample's blend weight is
        # known before its gradient.
        settled = grad_p[_BTF_UP] < 0 and grad_p[_MODULATES] == 0
        m = 0
        for i in range(n):
            for a in range(3):
                c, q = interp_unit.cell_weight(zyx[i, a], hi[a], w_bits, w_code)
                cell[a], w[a] = np.int64(c), np.int64(q)
            base = cell[0] * st_z + cell[1] * st_y + cell[2] * st_x
            value = _trilinear(vox, base, o1, o2, o3, o4, w[0], w[1], w[2], s_bits, w_bits, w_code)
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
                    # and the next cell (see _inner): the six samples without cell_weight.
                    for a in range(3):
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


def _laid_out(a: np.ndarray, shape, order: tuple[int, int, int]) -> np.ndarray:
    """Flat ``a`` (a ``(z, y, x)`` volume of ``shape``) with its axes in memory ``order``
    (slowest first)."""
    a = np.asarray(a).reshape(shape)
    return (a if order == (0, 1, 2) else a.transpose(order)).ravel()


def _strides(shape, order: tuple[int, int, int]) -> np.ndarray:
    """Element strides of the z, y, x axes of a ``shape`` volume laid out in ``order``."""
    strides = np.zeros(3, dtype=np.int64)
    step = 1
    for axis in reversed(order):
        strides[axis] = step
        step *= shape[axis]
    return strides


def _narrowest(a: np.ndarray) -> np.ndarray:
    """``a`` in the narrowest of uint8, uint16, int16, int32, int64 holding its values."""
    lo, hi = (int(a.min()), int(a.max())) if a.size else (0, 0)
    for dtype in (np.uint8, np.uint16, np.int16, np.int32):
        info = np.iinfo(dtype)
        if info.min <= lo and hi <= info.max:
            return a.astype(dtype)
    return a.astype(np.int64)


#: Per-volume voxels (and voxel differences) in the kernel's layouts, by datapath voxel
#: width and memory order; dropped with the volume.
_DERIVED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

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
        be, dp = backend, backend.dp
        # The raw voxels (and differences) in their narrowest integer type, promoted as
        # they are read: a quarter of the promoted int64 bytes, half of int32 (memory
        # traffic is what a 256^3 frame waits on).
        # Laid out with the principal axis slowest: a step's samples lie on one voxel
        # slice, read from contiguous rows instead of one cache line each (x principal).
        shape = be.volume.shape
        axis = be.plan.principal_axis
        order = (2, 0, 1) if axis == 2 else (0, 1, 2)
        # Kept per volume (as the golden renderer keeps its derived arrays): successive
        # frames of one volume and datapath width lay the voxels out once per order.
        derived = _DERIVED.setdefault(be.volume, {})
        key = (dp.voxel_bits, order)
        if key not in derived:
            derived[key] = _narrowest(_laid_out(be.raw, shape, order))
        self.vox = derived[key]
        self.shape = np.asarray(shape, dtype=np.int64)
        self.strides = _strides(shape, order)
        dz, dy, dx = (int(st) if n > 1 else 0 for st, n in zip(self.strides, shape, strict=True))
        self.offsets = np.array(
            [0, dx, dy, dx + dy, dz, dz + dx, dz + dy, dz + dy + dx], dtype=np.int64
        )  # interp.corner_offsets in this layout
        if not voxel_diffs:
            self.dxyz = (self.vox[:1],) * 3
        else:
            key = (dp.voxel_bits, order, "differences")
            if key not in derived:
                # One axis at a time, narrowed before it is laid out: a 512^3 volume
                # never holds three wide (int32) difference volumes at once.
                diffs = [
                    _laid_out(
                        _narrowest(gradient_unit.voxel_difference(be.raw, axis)), shape, order
                    )
                    for axis in (2, 1, 0)
                ]
                wide = np.result_type(*diffs)
                derived[key] = tuple(d.astype(wide, copy=False) for d in diffs)
            self.dxyz = derived[key]
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
