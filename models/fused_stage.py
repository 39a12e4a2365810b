"""The composite stage every compiled kernel shares: the unit functions it may call,
the gradient's world units and modulation, shading and blending of the visible samples,
and the per-frame constants packed for them.

# Ref: models/fused.py (the functional rung's kernel), models/machines/cube4/slice_kernel.py
#      and models/machines/volumepro/slab_kernel.py (the cycle rung's); docs/fidelity.md
#      ("How the functional rung simulates fast, exactly").

A kernel differs from another in where its samples come from (a volume's voxels, the
corner planes a machine's datapath delivered); what it does with a visible sample does
not, and is written here once: :func:`world_and_modulate`, :func:`shade_and_blend`
(inlined into each kernel, so a kernel specialised for constant formats keeps them) and
:class:`StageConstants` (the LUT, flags, shader, opacity-correction ROMs and the split of
a step's samples between the frame's threads).  Every rounding, lerp, root and division is
a ``*_raw`` function of its unit, registered with numba here (:data:`UNITS_HASH`,
:data:`STAGE_HASH`: the cache keys).
"""

from __future__ import annotations

import hashlib
import inspect
from pathlib import Path

import numba
import numpy as np
from numba.extending import register_jitable

from hwsim.core.threads import frame_threads
from hwsim.core.threads import pool as thread_pool
from hwsim.numerics import ROUNDING_CODES, SATURATIONS, round_scaled, round_shift_raw
from models.datapath import Datapath
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units import shade as shade_unit

__all__ = [
    "GRAD_FLAGS",
    "STAGE_HASH",
    "UNITS_HASH",
    "StageConstants",
    "eligible",
    "shade_and_blend",
    "slice_cell",
    "world_and_modulate",
]

#: The unit functions the kernel calls: registered with numba so compiled code may call
#: them (all take and return scalars only: array arguments would cost a reference-count
#: update per call), and hashed into the cache key.
_UNIT_FUNCTIONS = (
    round_shift_raw,
    round_scaled,
    interp_unit.cell_weight,
    interp_unit.promote_raw,
    interp_unit.lerp_raw,
    interp_unit.bilinear_raw,
    classify_unit.lut_index_raw,
    classify_unit.gm_index_raw,
    classify_unit.scale_alpha_raw,
    gradient_unit.isqrt_raw,
    gradient_unit.normal_raw,
    gradient_unit.normal_float_raw,
    gradient_unit.floor_div_raw,
    gradient_unit.bit_length_raw,
    shade_unit.light_terms_raw,
    shade_unit.cell_index_raw,
    shade_unit.specular_raw,
    shade_unit.shade_raw,
    composite_unit.ftb_weight_raw,
    composite_unit.ftb_colour_raw,
    composite_unit.btf_raw,
)
for _fn in _UNIT_FUNCTIONS:
    register_jitable(_fn)

#: Hash of the called unit functions' source (part of the compiled kernel's cache key).
UNITS_HASH = hashlib.sha256(
    "".join(inspect.getsource(fn) for fn in _UNIT_FUNCTIONS).encode()
).hexdigest()

#: Hash of this module's source and the unit functions': part of the cache key of every
#: kernel that inlines :func:`shade_and_blend` and its siblings (numba keys a cached
#: kernel by its own file and closure only, not by what it inlines).
STAGE_HASH = hashlib.sha256(
    (UNITS_HASH + Path(__file__).read_text(encoding="utf-8")).encode()
).hexdigest()

#: Kernel inputs ``grad_p`` (int64 flags and constants), by position.
_NEED_GRAD, _FROM_VOXELS, _WORLD, _MODULATES, _LIT = range(5)
_GM_SCALE, _GM_ENTRIES, _KA, _KD, _KS, _MAP_SIZE = range(5, 11)
#: Where other kernels find the flags :func:`world_and_modulate` takes in ``grad_p``:
#: world units, modulation, the magnitude's scale and the table's entries.
GRAD_FLAGS = (_WORLD, _MODULATES, _GM_SCALE, _GM_ENTRIES)
#: Back-to-front blending: the accumulator's fraction bits above 12 (-1: front to back).
_BTF_UP = 11


@numba.njit(inline="always")
def slice_cell(p, w_bits, w_code):
    """The in-slice cell of position ``p`` and its weight quantised from its own fraction
    (the slice machines' geometry unit, ``SliceOrderMachine.cell``: no clamp, their
    corner planes have margins), as the slice kernels ask for a gradient neighbour's."""
    c = np.floor(p)
    return np.int64(c), np.int64(round_scaled((p - c) * 2.0**w_bits, w_code))


@numba.njit(inline="always")
def world_and_modulate(gx, gy, gz, alpha, world, modulates, ratio, gm_scale, gm_entries, gm_table):
    """A sample's gradient ``(gx, gy, gz)`` to world units when the voxels are anisotropic
    (``gradient.to_world``), and its opacity ``alpha`` modulated by the gradient's
    magnitude when the transfer function does (``classify.modulate``): ``(gx, gy, gz,
    alpha)``."""
    if world:
        gx = round_shift_raw(gx * ratio[0], 12, 1)
        gy = round_shift_raw(gy * ratio[1], 12, 1)
        gz = round_shift_raw(gz * ratio[2], 12, 1)
    if modulates:
        mag = gradient_unit.isqrt_raw(gx * gx + gy * gy + gz * gz)
        gi = classify_unit.gm_index_raw(mag, gm_scale, gm_entries)
        alpha = classify_unit.scale_alpha_raw(alpha, gm_table[gi])
    return gx, gy, gz, alpha


@numba.njit(inline="always")
def shade_and_blend(
    rgba, vis_rays, g, m, grad_p, light, half, intensity, spec, maps, table, acc, ert_thr,
    alive, sat, f_bits, spec_entries, one, acc_code,
):  # fmt: skip
    """Shade (when lit) and blend the ``m`` visible samples a kernel kept (their colours
    and opacities ``rgba[:, :m]``, rays ``vis_rays[:m]``, gradients ``g[:, :m]``) into the
    accumulators ``acc``; counts saturations in ``sat``."""
    if grad_p[_LIT] != 0:
        # Pass 2, shading, in loops without branches over the visible samples (the
        # compiler vectorises them): normals, each light's terms, the colours.
        for j in range(m):
            g[0, j], g[1, j], g[2, j] = gradient_unit.normal_float_raw(
                g[0, j], g[1, j], g[2, j], f_bits
            )
        diffuse = np.zeros(m, np.int64)
        specular = np.zeros(m, np.int64)
        kd, ks, ka = grad_p[_KD], grad_p[_KS], grad_p[_KA]
        r_map = grad_p[_MAP_SIZE]
        for j in range(m if r_map > 0 else 0):  # reflectance maps: one lookup each
            ci = shade_unit.cell_index_raw(g[0, j], g[1, j], g[2, j], r_map)
            diffuse[j], specular[j] = maps[ci, 0], maps[ci, 1]
        for k in range(light.shape[0] if r_map == 0 else 0):
            lx, ly, lz, i_k = light[k, 0], light[k, 1], light[k, 2], intensity[k]
            hx, hy, hz = half[k, 0], half[k, 1], half[k, 2]
            for j in range(m):
                d, si = shade_unit.light_terms_raw(
                    g[0, j], g[1, j], g[2, j], lx, ly, lz, hx, hy, hz, i_k, kd,
                    spec_entries, f_bits,
                )  # fmt: skip
                diffuse[j] += d
                specular[j] += shade_unit.specular_raw(i_k, ks, spec[si])
        for c3 in range(3):
            for j in range(m):
                rgba[c3, j] = shade_unit.shade_raw(ka, rgba[c3, j], diffuse[j], specular[j])
    # Pass 3: composite.alpha saturation (counted), the opacity-correction ROM, the
    # blend (each ray at most once per call, so the order is free), termination.
    btf_up = grad_p[_BTF_UP]
    for j in range(m):
        alpha = rgba[3, j]
        if alpha < 0 or alpha > 4096:
            sat[0] += 1
            alpha = min(max(alpha, 0), 4096)
        alpha = table[alpha]
        ray = vis_rays[j]
        if btf_up >= 0:  # back to front: C = a c + (1 - a) C, one rounding each
            r = composite_unit.btf_raw(acc[ray, 0], rgba[0, j], alpha, btf_up, acc_code)
            gr = composite_unit.btf_raw(acc[ray, 1], rgba[1, j], alpha, btf_up, acc_code)
            b = composite_unit.btf_raw(acc[ray, 2], rgba[2, j], alpha, btf_up, acc_code)
            a_new = composite_unit.btf_raw(acc[ray, 3], 4096, alpha, btf_up, acc_code)
        else:
            aw = composite_unit.ftb_weight_raw(acc[ray, 3], alpha, one, acc_code)
            r = acc[ray, 0] + composite_unit.ftb_colour_raw(aw, rgba[0, j], acc_code)
            gr = acc[ray, 1] + composite_unit.ftb_colour_raw(aw, rgba[1, j], acc_code)
            b = acc[ray, 2] + composite_unit.ftb_colour_raw(aw, rgba[2, j], acc_code)
            a_new = acc[ray, 3] + aw
        for c4, v in enumerate((r, gr, b, a_new)):
            if v < 0 or v > one:  # composite.acc saturation (counted)
                sat[1] += 1
                v = min(max(v, 0), one)
            acc[ray, c4] = v
        if ert_thr >= 0:
            alive[ray] = acc[ray, 3] < ert_thr


#: A step is cut into runs for several threads only above this many samples per thread:
#: below it, handing a run to a thread costs about what it saves.
_SAMPLES_PER_THREAD = 2048
#: Samples per block of a thread's run (:meth:`StageConstants.run_parts`).
_BLOCK = 256


def eligible(backend) -> bool:
    """Whether :class:`CompositeKernel` can run ``backend``'s composite stage (see Scope;
    a step whose samples differ in length still takes the chain, :meth:`~CompositeKernel.table`)."""
    be = backend
    if be.mode != "composite" or be.pre_classified or be.exercise_unused:
        return False
    if be.cursor is not None:  # the kernel draws no cursor
        return False
    if be.multilut is not None or be.depth is not None or be.illum_table is not None:
        return False
    # One shader for the frame (parallel views): Phong or reflectance maps.
    return not be.scene.lit or be.shader is not None


class StageConstants:
    """The per-frame constants of one back end's composite stage, packed for a compiled
    kernel: the LUT, gradient and shading flags, the shader, the opacity-correction ROMs
    (:meth:`table`), the formats (``config``), and how a step's samples are cut into
    runs for the frame's threads (:meth:`run_parts`)."""

    def __init__(self, backend) -> None:
        be, dp = backend, backend.dp
        self.backend = be
        shift = dp.voxel_bits + be.S - int(np.log2(dp.classify.entries))
        cfg = dp.composite
        self.config = (
            be.S,
            dp.interp.weight_bits,
            ROUNDING_CODES[dp.interp.rounding],
            shift,
            dp.classify.entries,
            dp.gradient.normal_frac_bits,
            dp.shade.spec_table_entries,
            1 << cfg.acc_frac_bits,
            ROUNDING_CODES[cfg.acc.rounding],
        )
        self.rgb12 = np.ascontiguousarray(be.lut.rgb12, dtype=np.int64)
        self.alpha12 = np.ascontiguousarray(be.lut.alpha12, dtype=np.int64)
        spacing = np.asarray(be.volume.spacing, dtype=np.float64)[::-1]
        self.ratio = np.floor(spacing.min() / spacing * (1 << 12) + 0.5).astype(np.int64)
        world = not np.all(self.ratio == 1 << 12)
        modulates = be.need_grad and be.transfer.modulates
        lit = bool(be.scene.lit)
        sh = be.shader if lit else None
        self.grad_p = np.array(
            [
                be.need_grad,
                be.need_grad and dp.gradient.source == "voxel",
                world,
                modulates,
                lit,
                be.gm_scale if modulates else 0,
                dp.classify.gm_entries,
                sh.ka if sh else 0,
                sh.kd if sh else 0,
                sh.ks if sh else 0,
                dp.shade.map_size if sh is not None and sh.maps is not None else 0,
                dp.composite.acc_frac_bits - 12 if be.plan.back_to_front else -1,
            ],
            dtype=np.int64,
        )
        # A cell's diffuse and specular entries side by side, in the narrowest type that
        # holds them: one cache line a lookup, and the map a quarter of int64 rows (its
        # reads missed the cache: about a sixth of the VolPack benchmark's kernel).
        self.maps = np.zeros((1, 2), np.int16)
        if sh is not None and sh.maps is not None:
            both = np.stack([np.asarray(sh.maps[0]), np.asarray(sh.maps[1])], axis=1)
            lo, hi = int(both.min()), int(both.max())
            wide = next(
                t for t in (np.int16, np.int32, np.int64)
                if np.iinfo(t).min <= lo and hi <= np.iinfo(t).max
            )  # fmt: skip
            self.maps = np.ascontiguousarray(both, dtype=wide)
        self.gm_table = (
            np.asarray(be.gm_table, dtype=np.int64) if modulates else np.zeros(1, np.int64)
        )
        if sh is not None:
            self.light = np.ascontiguousarray(sh.light, dtype=np.int64)
            self.half = np.ascontiguousarray(sh.half, dtype=np.int64).reshape(-1, 3)
            self.intensity = np.asarray(sh.intensity, dtype=np.int64)
            self.spec = np.asarray(sh.spec, dtype=np.int64)
        else:
            self.light = self.half = np.zeros((0, 3), np.int64)
            self.intensity, self.spec = np.zeros(0, np.int64), np.zeros(2, np.int64)
        self.ert_thr = -1  # early termination off
        if be.ert < 1.0:
            self.ert_thr = int(cfg.acc.quantize(max(be.ert, 0.0)))
        self._tables: dict[float, np.ndarray] = {}
        self._no_factor = np.zeros(0, dtype=np.int64)
        #: The machine's own formats: a kernel may be specialised for them; overridden
        #: widths (a width sweep) share a generic kernel.
        self.own_formats = dp == Datapath.for_volume(be.arch, be.volume)

    def table(self, dt) -> np.ndarray | None:
        """The opacity-correction ROM of a step whose samples all have step length
        ``dt`` (a float, or an array of one repeated value: parallel shear-image steps);
        None when the step must take the unit chain (unequal lengths, or an exponent
        outside ``composite.ratio``, which the chain counts or refuses per call)."""
        if not np.isscalar(dt):
            if dt.size == 0 or dt.min() != dt.max():
                return None
            dt = dt.flat[0]
        dt = float(dt)
        table = self._tables.get(dt)
        if table is None:
            be, fmt = self.backend, self.backend.dp.composite.ratio
            k = np.asarray(dt) / be.ref  # what Backend._composite hands correct_opacity
            raw = round_scaled(k * 2.0**fmt.frac_bits, ROUNDING_CODES[fmt.rounding])
            if not 1 <= raw <= fmt.raw_max:
                return None
            table = self._tables[dt] = composite_unit.correction_for(k, be.dp.composite)
        return table

    def run_parts(self, run_part, per_sample: tuple, factor, state, table) -> None:
        """``run_part(*per_sample, factor, state, table)`` over a step's samples (arrays
        ``per_sample``, the first axis the sample; ``factor`` per sample or None), counting
        the saturations it returns.

        A step's rays are distinct, so its samples touch disjoint accumulators: with
        :func:`frame_threads` above one, large steps are cut into that many runs of
        samples composited at once, on this thread and the pool's (the kernels release
        the GIL), each counting its own saturations; the result is the same bits in any
        case."""
        factor = self._no_factor if factor is None else np.asarray(factor, dtype=np.int64)
        n, threads = per_sample[0].shape[0], frame_threads()
        parts = min(threads, n // _SAMPLES_PER_THREAD)
        if parts <= 1:
            sat = run_part(*per_sample, factor, state, table)
        else:
            # Runs of interleaved blocks (block b goes to run b mod parts): neighbouring
            # samples cost alike (transparent ones next to each other), so the runs
            # balance; blocks, not single samples, so that two threads do not write the
            # same cache lines of the accumulators (neighbouring rays) all the time.
            block = (np.arange(n) // _BLOCK) % parts

            def part(k: int):
                cut = block == k
                f = factor[cut] if factor.size else factor
                return (*(a[cut] for a in per_sample), f)

            pool = thread_pool(threads)
            runs = [pool.submit(run_part, *part(k), state, table) for k in range(1, parts)]
            sat = run_part(*part(0), state, table)  # this thread takes run 0
            sat = sat + sum(r.result() for r in runs)
        self.count_saturations(sat)

    def count_saturations(self, sat: np.ndarray) -> None:
        """Add a kernel's saturation counts (``composite.alpha``, ``composite.acc``)."""
        if sat[0]:
            SATURATIONS[composite_unit.ALPHA.name] += int(sat[0])
        if sat[1]:
            SATURATIONS[self.backend.dp.composite.acc.name] += int(sat[1])
