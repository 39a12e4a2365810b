"""A per-pixel bound on |golden - functional|, derived from the datapath's formats.

The functional rung differs from the float64 golden renderer at the same sample positions
only by the fixed-point arithmetic of docs/numerics.md: every format, rounding and
table is known, so the difference a pixel may show is computable from the scene's inputs
and the formats, before either image is looked at.  :func:`pixel_bound` computes it, one
bound per pixel and channel; :func:`agreement` compares two images against it.  The
derivation, with its assumptions, is in docs/numerics.md ("End to end: a bound derived
from the formats").

What the bound is built from (nothing here is fitted to a measured image):

* the sample positions of the plan and the scene's inputs (volume, transfer function,
  lights, material), which both sides share;
* the datapath's formats (:class:`models.datapath.Datapath`: weight and fraction bits,
  LUT size and storage widths, normal, coefficient and table widths, accumulator and
  output widths) and the roundings docs/numerics.md states for each;
* float64 evaluations of the ideal (golden) quantities, written here from the documented
  formulas: no function of ``hwsim.golden`` that computes a sample, a colour or a
  composite is called, so an error in the golden renderer does not move the bound.

Per sample, each stage gives an interval that must hold the functional rung's value (the
quantised position fractions, the interpolated value, the LUT entries it can index, the
normal and dot products, the shaded colour, the corrected opacity); the distance from the
golden value to the far end of that interval is the sample's error.  Along a ray the
sample errors are composited by an exact telescoping identity (golden samples in front
of sample ``j``, functional samples behind it), then the compositor's roundings and the
output rounding are added.  Shear-warp's base-plane warp is bilinear with non-negative
weights, so the base-plane bound warps into the image's.

Covered: composite (front to back and back to front, post-classification, Phong or
reflectance maps, lit or not, any lights, parallel or perspective), MIP, MinIP, X-ray and
iso on trilinear interpolation.  Anything else (pre-classification, gradient-magnitude
modulation, multi-LUT classification, embedded geometry, the cursor, crop and cut planes,
early ray termination) raises ``NotImplementedError`` naming it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from hwsim.golden import make_plan, render_golden
from hwsim.golden.shading import cube_face
from hwsim.numerics import psnr
from hwsim.run.fidelity import algorithms, resolve_arch
from hwsim.spec.scene import Light
from hwsim.spec.transfer import resolve_transfer
from models.datapath import Datapath
from models.frame import frame_of
from models.functional import render_functional

__all__ = [
    "Agreement",
    "agreement",
    "golden_at_machine",
    "machine_pair",
    "pixel_bound",
]

ONE12 = 4096.0
SQRT3 = float(np.sqrt(3.0))


# ------------------------------------------------------------------------------ the API


@dataclass(frozen=True)
class Agreement:
    """Golden against functional, judged by the derived bound.

    ``excess`` is ``max(|golden - functional| - bound)`` over pixels and channels: the
    images agree when it is at most 0.  ``ratio`` is ``max(|golden - functional| /
    bound)`` (the share of the bound the worst pixel uses); ``violations`` counts the
    values over the bound; ``psnr`` is reported, not judged.
    """

    excess: float
    ratio: float
    violations: int
    max_error: float
    bound_min: float
    bound_median: float
    psnr: float

    @property
    def ok(self) -> bool:
        return self.excess <= 0.0

    def __str__(self) -> str:
        return (
            f"excess {self.excess:+.5f} ({self.violations} values over the bound), "
            f"worst |g-f|/bound {self.ratio:.3f}, max |g-f| {self.max_error:.5f}, "
            f"bound min {self.bound_min:.5f} median {self.bound_median:.5f}, "
            f"PSNR {self.psnr:.1f} dB"
        )


def agreement(golden: np.ndarray, fixed: np.ndarray, bound: np.ndarray) -> Agreement:
    """Compare two images (same shape) against a :func:`pixel_bound`."""
    golden, fixed = np.asarray(golden, float), np.asarray(fixed, float)
    if golden.shape != fixed.shape or golden.shape != bound.shape:
        raise ValueError(f"shapes differ: {golden.shape}, {fixed.shape}, {bound.shape}")
    err = np.abs(golden - fixed)
    over = err - bound
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bound > 0, err / bound, np.where(err > 0, np.inf, 0.0))
    return Agreement(
        excess=float(over.max()),
        ratio=float(ratio.max()),
        violations=int(np.count_nonzero(over > 0)),
        max_error=float(err.max()),
        bound_min=float(bound.min()),
        bound_median=float(np.median(bound)),
        psnr=float(psnr(golden, fixed)),
    )


def golden_at_machine(scene, volume, arch, transfer=None):
    """Golden at ``arch``'s sample positions *and with its algorithms*, as
    ``hwsim.run.fidelity.render(fidelity="golden", arch=...)`` renders it: the machine's
    gradient source where the scene names none, and its reflectance maps where it shades
    by them (``render_golden(..., reflectance_map=map_size)``); every planned position
    (``leap=False``).  Returns ``(scene as rendered, GoldenResult)``: the functional rung
    must be given the same scene."""
    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    chosen = algorithms(machine)
    if scene.render.gradient is None:
        scene = scene.replace(render=dataclasses.replace(scene.render, gradient=chosen.gradient))
    tf = transfer if transfer is not None else resolve_transfer(scene.transfer, volume)
    maps = chosen.map_size if chosen.shading == "reflectance-map" else None
    result = render_golden(
        scene, volume, tf, sampling=machine.order, leap=False, reflectance_map=maps
    )
    return scene, result


def machine_pair(scene, volume, arch, transfer=None):
    """``(golden, functional, bound)`` of one frame: golden with the machine's algorithms
    (:func:`golden_at_machine`), the functional rung on the same plan, and
    :func:`pixel_bound`."""
    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    tf = transfer if transfer is not None else resolve_transfer(scene.transfer, volume)
    scene, golden = golden_at_machine(scene, volume, machine, tf)
    plan = make_plan(scene, volume, machine.order)
    fixed = render_functional(frame_of(scene, volume, tf, machine, plan))
    return golden, fixed, pixel_bound(scene, volume, machine, tf)


def pixel_bound(scene, volume, arch, transfer=None) -> np.ndarray:
    """Per pixel and channel, an upper bound on ``|golden - functional|`` for ``scene``
    on ``arch`` at the machine's sample positions (golden rendered as
    :func:`golden_at_machine` renders it); shaped like the images.

    Derived from ``arch``'s datapath formats for ``volume`` (docs/numerics.md); computed
    from the scene's inputs only, never from either image.
    """
    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    chosen = algorithms(machine)
    if scene.render.gradient is None:
        scene = scene.replace(render=dataclasses.replace(scene.render, gradient=chosen.gradient))
    tf = transfer if transfer is not None else resolve_transfer(scene.transfer, volume)
    dp = Datapath.for_volume(machine, volume)
    _refuse_unsupported(scene, tf, dp)
    plan = make_plan(scene, volume, machine.order)
    return _Bound(scene, volume, tf, dp, plan).run()


def _refuse_unsupported(scene, tf, dp) -> None:
    r = scene.render
    reasons = [
        (tf.order == "pre" and r.mode == "composite", "pre-classification"),
        (tf.modulates and r.mode == "composite", "gradient-magnitude opacity modulation"),
        (tf.modulates_illumination and scene.lit, "gradient-magnitude illumination"),
        (scene.classification is not None, "multi-LUT classification"),
        (scene.geometry is not None, "embedded geometry"),
        (scene.cursor is not None, "the 3-D cursor"),
        (scene.crop is not None, "crop"),
        (bool(scene.cut_planes), "cut planes"),
        (r.early_termination < 1.0 and r.mode == "composite", "early ray termination"),
        (r.interpolation != "trilinear", f"{r.interpolation} interpolation"),
        (
            scene.render.gradient != dp.gradient.source and scene.lit,
            "a gradient source other than the machine's",
        ),
    ]
    for refused, what in reasons:
        if refused:
            raise NotImplementedError(f"numeric_bound does not cover {what}")


# ---------------------------------------------------------------------- the formats' maps


def _round(x, rounding: str):
    """A real (scaled to LSBs) rounded to an integer by a documented rounding mode."""
    if rounding == "nearest-up":
        return np.floor(x + 0.5)
    if rounding == "nearest-even":
        return np.round(x)
    if rounding == "truncate":
        return np.trunc(x)
    return np.floor(x)


def _half_lsb(rounding: str) -> float:
    """Largest rounding error, in LSBs, of a rounding mode (nearest: 1/2, directed: 1)."""
    return 0.5 if rounding.startswith("nearest") else 1.0


def _q(x, bits: int):
    """Nearest-up quantisation to ``bits`` fraction bits (SQ1.F vectors, UQ4.8
    coefficients, UQ4.F exponents): ``floor(x 2**bits + 1/2) / 2**bits``."""
    return np.floor(np.asarray(x, dtype=np.float64) * 2.0**bits + 0.5) / 2.0**bits


def _unorm_to_uq12(x, bits: int):
    """A [0, 1] value stored as unorm ``bits`` (nearest-up) and read out as UQ1.12
    (``round(u 4096 / (2**n - 1))`` half up): both steps monotone, 0 and 1 exact."""
    full = (1 << bits) - 1
    stored = np.floor(np.asarray(x, dtype=np.float64) * full + 0.5)
    return np.floor((stored * (2 * ONE12) + full) / (2 * full)) / ONE12


def _tf_range(points: np.ndarray, column: np.ndarray, x0, x1):
    """Min and max of a piecewise-linear function (``numpy.interp``: constant outside its
    points) over ``[x0, x1]``: the ends and the control points inside."""
    a, b = np.interp(x0, points, column), np.interp(x1, points, column)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    for xk, yk in zip(points, column, strict=True):
        inside = (x0 < xk) & (xk < x1)
        lo = np.where(inside, np.minimum(lo, yk), lo)
        hi = np.where(inside, np.maximum(hi, yk), hi)
    return lo, hi


def _voxel_map(volume, bits: int) -> tuple[float, float, float]:
    """``(offset, scale, conversion error in raw units)`` of docs/numerics.md's voxel
    rules: unsigned data of at most ``bits`` bits shifted up (exact), signed data whose
    range fits offset by its minimum (exact), anything else mapped linearly onto
    ``[0, 2**bits - 1]`` rounding half up (half a raw step)."""
    data = volume.data
    top = (1 << bits) - 1
    lo, hi = volume.value_range
    if data.dtype.kind == "u" and volume.bits <= bits and hi <= (1 << volume.bits) - 1:
        return 0.0, 2.0 ** -(bits - volume.bits), 0.0
    if data.dtype.kind in "iu" and hi - lo <= top:
        return float(lo), 1.0, 0.0
    if hi <= lo:
        return float(lo), 1.0, 0.0
    return float(lo), (hi - lo) / top, 0.5


def _chord(r):
    """Largest distance between the unit vectors of ``g`` and ``g + e`` with
    ``|e| <= r |g|``: ``2 sin(theta / 2)`` with ``sin theta = r``; 2 when ``r >= 1``."""
    r = np.asarray(r, dtype=np.float64)
    inside = np.sqrt(np.maximum(1.0 - np.minimum(r, 1.0) ** 2, 0.0))
    return np.where(r < 1.0, np.sqrt(np.maximum(2.0 - 2.0 * inside, 0.0)), 2.0)


# ------------------------------------------------------------------------- the bound


class _Field:
    """A per-voxel field (golden units: raw voxel units, float64) sampled as the
    interpolator samples it, with the per-axis spreads of each cell."""

    def __init__(self, data: np.ndarray, conv: float) -> None:
        self.flat = np.ascontiguousarray(data, dtype=np.float64).ravel()
        self.conv = conv  # per-voxel conversion error of the functional rung's copy


class _Bound:
    def __init__(self, scene, volume, tf, dp: Datapath, plan) -> None:
        self.scene, self.volume, self.tf, self.dp, self.plan = scene, volume, tf, dp, plan
        self.mode = scene.render.mode
        self.shape = np.asarray(volume.shape, dtype=np.int64)
        self.offset, self.scale, conv = _voxel_map(volume, dp.voxel_bits)
        raw = (np.asarray(volume.data, dtype=np.float64) - self.offset) / self.scale
        self.value = _Field(raw, conv)
        ip = dp.interp
        self.W, self.S = ip.weight_bits, ip.sample_frac_bits
        self.wround = ip.rounding
        #: One lerp's rounding, raw voxel units.
        self.r = _half_lsb(ip.rounding) * 2.0**-self.S
        self.ref = min(volume.spacing)
        self.lit = scene.lit
        if self.lit:
            self._setup_light(raw, conv)

    # ---------------------------------------------------------------- interpolation

    def cells(self, zyx: np.ndarray):
        """Corner indices ``(8, n)`` (``c = 4 dz + 2 dy + dx``), golden fractions ``f``
        and quantised fractions ``fq``, both ``(n, 3)`` along ``(z, y, x)``."""
        hi = self.shape.astype(np.float64) - 1.0
        p = np.minimum(np.maximum(zyx, 0.0), hi)
        i0 = np.minimum(np.floor(p), np.maximum(hi - 1.0, 0.0))
        f = p - i0
        fq = np.minimum(_round(f * 2.0**self.W, self.wround), 2.0**self.W) / 2.0**self.W
        i0 = i0.astype(np.int64)
        i1 = np.minimum(i0 + 1, self.shape - 1)
        ny, nx = self.shape[1], self.shape[2]
        idx = np.empty((8, zyx.shape[0]), dtype=np.int64)
        for c in range(8):
            z = np.where((c >> 2) & 1, i1[:, 0], i0[:, 0])
            y = np.where((c >> 1) & 1, i1[:, 1], i0[:, 1])
            x = np.where(c & 1, i1[:, 2], i0[:, 2])
            idx[c] = (z * ny + y) * nx + x
        return idx, f, fq

    @staticmethod
    def trilinear(v: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Float64 trilinear of corners ``v (8, n)`` at fractions ``f (n, 3)``: x, y, z."""
        fz, fy, fx = f[:, 0], f[:, 1], f[:, 2]
        x = v[0::2] + fx * (v[1::2] - v[0::2])  # (4, n): (dz, dy) pairs
        y = x[0::2] + fy * (x[1::2] - x[0::2])  # (2, n): dz
        return y[0] + fz * (y[1] - y[0])

    def weight_error(self, v: np.ndarray, f: np.ndarray, fq: np.ndarray, conv: float):
        """Bound on |fixed-point lerps - float trilinear| of corners ``v``: per axis the
        cell's largest difference along it times the quantised weight's error, plus one
        lerp rounding per axis (x, y, z: the lerps are convex, so errors do not grow),
        plus the conversion error of the corners."""
        dw = np.abs(fq - f)
        dx = np.abs(v[1::2] - v[0::2]).max(axis=0)
        dy = np.abs(v[[2, 3, 6, 7]] - v[[0, 1, 4, 5]]).max(axis=0)
        dz = np.abs(v[4:] - v[:4]).max(axis=0)
        c2 = 2.0 * conv
        return (
            (dx + c2) * dw[:, 2] + (dy + c2) * dw[:, 1] + (dz + c2) * dw[:, 0] + 3 * self.r + conv
        )

    def sample(self, zyx: np.ndarray):
        """Golden raw value ``(n,)`` and the bound on the functional sample's error."""
        idx, f, fq = self.cells(zyx)
        v = self.value.flat[idx]
        return self.trilinear(v, f), self.weight_error(v, f, fq, self.value.conv)

    # --------------------------------------------------------------- classification

    def entry_values(self, v: np.ndarray, e: np.ndarray):
        """The value interval ``[lo, hi]`` (volume units) of the LUT entries a sample in
        ``[v - e, v + e]`` (raw units) can index: nearest entry, half up, clamped."""
        cl = self.dp.classify
        bits = self.dp.voxel_bits
        per_entry = 2.0**bits / cl.entries  # raw units per entry
        lo = np.clip(np.floor((v - e) / per_entry + 0.5), 0, cl.entries - 1) * per_entry
        hi = np.clip(np.floor((v + e) / per_entry + 0.5), 0, cl.entries - 1) * per_entry
        return self.offset + self.scale * lo, self.offset + self.scale * hi

    def classified(self, v: np.ndarray, e: np.ndarray):
        """Golden RGBA ``(n, 4)`` and the functional rung's UQ1.12 RGBA interval."""
        tf, cl = self.tf, self.dp.classify
        value = self.offset + self.scale * v
        x0, x1 = self.entry_values(v, e)
        golden = np.stack([np.interp(value, tf.values, tf.rgba[:, c]) for c in range(4)], 1)
        lo = np.empty_like(golden)
        hi = np.empty_like(golden)
        for c in range(4):
            a, b = _tf_range(tf.values, tf.rgba[:, c], x0, x1)
            bits = cl.color_bits if c < 3 else cl.alpha_bits
            lo[:, c], hi[:, c] = _unorm_to_uq12(a, bits), _unorm_to_uq12(b, bits)
        return golden, lo, hi

    def correction(self, k: float) -> np.ndarray:
        """The opacity-correction table of docs/numerics.md for exponent ``k``: 4097
        entries ``1 - (1 - i/4096)**k'`` rounded half up to UQ1.12, ``k'`` the UQ4.R
        quantisation of ``k``, ``0 -> 0``, ``1 -> 1``, non-decreasing."""
        cache = self.__dict__.setdefault("_tables", {})
        kq = float(_q(k, self.dp.composite.ratio_frac_bits))
        if kq not in cache:
            a = np.arange(4097) / ONE12
            t = np.floor(ONE12 * (1.0 - (1.0 - a) ** kq) + 0.5)
            t[0], t[-1] = 0.0, ONE12
            cache[kq] = np.maximum.accumulate(np.clip(t, 0, ONE12)) / ONE12
        return cache[kq]

    def corrected(self, alpha, lo, hi, k):
        """Golden corrected opacity and the functional rung's interval."""
        a = 1.0 - (1.0 - alpha) ** k
        if np.ndim(k) == 0:
            table = self.correction(float(k))
            return a, table[np.rint(lo * ONE12).astype(int)], table[np.rint(hi * ONE12).astype(int)]
        out_lo, out_hi = np.empty_like(a), np.empty_like(a)
        for kk in np.unique(k):
            sel = k == kk
            table = self.correction(float(kk))
            out_lo[sel] = table[np.rint(lo[sel] * ONE12).astype(int)]
            out_hi[sel] = table[np.rint(hi[sel] * ONE12).astype(int)]
        return a, out_lo, out_hi

    # -------------------------------------------------------------------- gradients

    def _setup_light(self, raw: np.ndarray, conv: float) -> None:
        scene, dp, plan = self.scene, self.dp, self.plan
        self.source = dp.gradient.source
        self.F = dp.gradient.normal_frac_bits
        if self.source == "voxel":
            # Converted voxels within ``conv`` each: differences within 2 conv, the
            # faces' doubled one-sided differences within 4 conv.
            self.diffs = [_Field(d, 4.0 * conv) for d in _voxel_differences(raw)]
        sp = np.asarray(self.volume.spacing, dtype=np.float64)[::-1]  # x, y, z
        self.ratio = sp.min() / sp
        self.ratio_q = _q(self.ratio, 12)
        self.anisotropic = not np.all(self.ratio_q == 1.0)
        m = scene.material
        c8 = 8  # coefficients and intensities: UQ4.8
        self.ka, self.kd, self.ks, self.n = m.ambient, m.diffuse, m.specular, m.shininess
        self.ka_q, self.kd_q, self.ks_q = (
            float(_q(x, c8)) for x in (m.ambient, m.diffuse, m.specular)
        )
        lights = scene.lights or (Light(),)
        self.lights = [
            (plan.camera.light_to_world(li.direction, li.space), li.intensity) for li in lights
        ]
        self.I_q = [float(_q(i, c8)) for _, i in self.lights]
        self.maps = dp.shade.map_size if dp.shade.method == "reflectance-map" else None
        self.entries = dp.shade.spec_table_entries

    def gradient(self, zyx: np.ndarray):
        """Golden gradient ``(n, 3)`` xyz (raw units, scaled to world directions) and the
        bound on the Euclidean norm of the functional gradient's error."""
        if self.source == "voxel":
            idx, f, fq = self.cells(zyx)
            g = np.empty((zyx.shape[0], 3))
            err = np.empty((zyx.shape[0], 3))
            for a, fld in enumerate(self.diffs):  # x, y, z components
                v = fld.flat[idx]
                g[:, a] = self.trilinear(v, f)
                err[:, a] = self.weight_error(v, f, fq, fld.conv)
        else:
            g, err = self._sample_gradient(zyx)
        if self.anisotropic:
            err = err * self.ratio_q + np.abs(g) * np.abs(self.ratio_q - self.ratio) + self.r
            g = g * self.ratio
        return g, np.sqrt(np.sum(err * err, axis=1))

    def _sample_gradient(self, zyx: np.ndarray):
        n = zyx.shape[0]
        g = np.empty((n, 3))
        err = np.empty((n, 3))
        flat, conv = self.value.flat, self.value.conv
        for axis in range(3):  # z, y, x index axes -> components 2, 1, 0
            step = np.zeros(3)
            step[axis] = 1.0
            ia, fa, qa = self.cells(zyx + step)
            ib, fb, qb = self.cells(zyx - step)
            va, vb = flat[ia], flat[ib]
            g[:, 2 - axis] = self.trilinear(va, fa) - self.trilinear(vb, fb)
            independent = self.weight_error(va, fa, qa, conv) + self.weight_error(vb, fb, qb, conv)
            # Where both neighbours have the same quantised weights (every sample not
            # clamped at a face), their difference is one interpolation of the corner
            # differences with those weights, plus each side's lerp roundings.
            same = np.all(qa == qb, axis=1) & np.all(np.abs(fa - fb) < 1e-9, axis=1)
            dv = va - vb
            shared = self.weight_error(dv, fa, qa, 2.0 * conv) + 3 * self.r
            shared += 3 * np.abs(fa - fb).max(axis=1) * (vb.max(axis=0) - vb.min(axis=0))
            err[:, 2 - axis] = np.where(same, np.minimum(shared, independent), independent)
        return g, err

    # ---------------------------------------------------------------------- shading

    def shaded(self, rgb, lo, hi, g, dg, toward_viewer, viewer_q):
        """Golden shaded colour ``(n, 3)`` and the functional rung's interval, for
        golden colours ``rgb``, functional colour interval ``[lo, hi]`` (UQ1.12),
        golden gradients ``g`` with error norm bound ``dg``; ``toward_viewer`` golden's
        unit vectors (``(3,)`` or ``(n, 3)``), ``viewer_q`` the functional rung's."""
        F = self.F
        mag = np.sqrt(np.sum(g * g, axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(mag > 1e-12, dg / mag, np.inf)
            normal = np.where(mag[:, None] > 1e-12, -g / mag[:, None], 0.0)
        # Direction of the functional gradient against golden's, then its SQ1.F normal
        # (below 2**-F per component of the exact quotient).
        rho = _chord(rel)
        if self.maps is None:
            shading_normal = normal
            nu = rho + SQRT3 * 2.0**-F
        else:
            shading_normal, nu = self._map_normals(normal, rho + 2 * SQRT3 * 2.0**-F)
        nu = np.where(rel < 1.0, nu, 2.0 + SQRT3 * 2.0**-F)
        diffuse_g = np.zeros(g.shape[0])
        spec_g = np.zeros(g.shape[0])
        d_lo, d_hi = np.zeros(g.shape[0]), np.zeros(g.shape[0])
        s_lo, s_hi = np.zeros(g.shape[0]), np.zeros(g.shape[0])
        dot_round = 2.0**-13  # the dot products rounded to UQ1.12
        for (light, intensity), i_q in zip(self.lights, self.I_q, strict=True):
            lq = _q(light, F)
            h = _unit(toward_viewer + light)
            hq = _q(_unit(viewer_q + light), F)
            x_l = shading_normal @ light
            x_h = _rowdot(shading_normal, h)
            e_l = nu * np.linalg.norm(lq) + np.linalg.norm(lq - light) + dot_round
            e_h = nu * _norm(hq) + _norm(hq - h) + dot_round
            diffuse_g += intensity * self.kd * np.maximum(x_l, 0.0)
            spec_g += intensity * self.ks * _power(np.maximum(x_h, 0.0), self.n)
            ikd, iks = i_q * self.kd_q, i_q * self.ks_q
            d_lo += np.maximum(ikd * np.clip(x_l - e_l, 0.0, 1.0) - dot_round, 0.0)
            d_hi += ikd * np.clip(x_l + e_l, 0.0, 1.0) + dot_round
            e = self.entries
            i_lo = np.floor(np.clip(x_h - e_h, 0.0, 1.0) * e + 0.5)
            i_hi = np.floor(np.clip(x_h + e_h, 0.0, 1.0) * e + 0.5)
            t_lo = np.floor(_power(i_lo / e, self.n) * ONE12 + 0.5) / ONE12
            t_hi = np.floor(_power(i_hi / e, self.n) * ONE12 + 0.5) / ONE12
            s_lo += np.maximum(iks * t_lo - dot_round, 0.0)
            s_hi += iks * t_hi + dot_round
        golden = np.clip(self.ka * rgb + diffuse_g[:, None] * rgb + spec_g[:, None], 0.0, 1.0)
        r = 2.0**-13  # the two products rounded to UQ1.12
        f_lo = np.clip(self.ka_q * lo - r + d_lo[:, None] * lo - r + s_lo[:, None], 0.0, 1.0)
        f_hi = np.clip(self.ka_q * hi + r + d_hi[:, None] * hi + r + s_hi[:, None], 0.0, 1.0)
        return golden, f_lo, f_hi

    def _map_normals(self, normal: np.ndarray, rho: np.ndarray):
        """Reflectance maps: golden's shading normal (its cube-map cell's centre) and the
        bound on the distance from the functional rung's (the SQ1.F-rounded centre of the
        cell its normal falls in).  Where every normal within ``rho`` of golden's lies in
        golden's cell, both shade at that centre; elsewhere the cells may differ by the
        cell's radius ``sqrt(2) / size`` on the functional side plus ``rho`` plus golden's
        own distance to its centre."""
        size = self.maps
        a, axis, rows, major, others = cube_face(normal)  # golden's face rule
        centre = np.zeros_like(normal)
        centre[rows, axis] = np.sign(normal[rows, axis])
        inside = major - rho > np.max(np.where(np.arange(3) == axis[:, None], 0.0, a), axis=1) + rho
        safe = np.where(major > 1e-12, major, 1.0)
        for k in (0, 1):
            o = normal[rows, others[:, k]]
            u = o / safe
            cell = np.clip(np.floor((u + 1.0) * 0.5 * size), 0, size - 1)
            centre[rows, others[:, k]] = (cell + 0.5) / size * 2.0 - 1.0
            lo_m, hi_m = np.maximum(major - rho, 1e-12), major + rho
            u_lo = np.where(o - rho >= 0, (o - rho) / hi_m, (o - rho) / lo_m)
            u_hi = np.where(o + rho >= 0, (o + rho) / lo_m, (o + rho) / hi_m)
            c_lo = np.clip(np.floor((u_lo + 1.0) * 0.5 * size), 0, size - 1)
            c_hi = np.clip(np.floor((u_hi + 1.0) * 0.5 * size), 0, size - 1)
            inside &= (c_lo == cell) & (c_hi == cell)
        centre = _unit_rows(centre)
        centre[major <= 1e-12] = 0.0
        q_err = _norm(_q(centre, self.F) - centre)
        far = SQRT3 * 2.0 ** -(self.F + 1) + np.sqrt(2.0) / size + rho + _norm(normal - centre)
        return centre, np.where(inside, q_err, far)

    # ------------------------------------------------------------------------- run

    def run(self) -> np.ndarray:
        mode = self.mode
        if mode == "composite":
            acc = self._composite()
        elif mode in ("mip", "minip"):
            acc = self._extreme()
        elif mode == "xray":
            acc = self._xray()
        else:
            acc = self._iso()
        return self.plan.to_image(acc, 0.0)

    def _viewer_q(self, step):
        """The functional rung's vector toward the viewer for a step's rays."""
        return self.plan.toward_viewer(step.rays)

    def _samples(self):
        """Per step: ``(rays, golden a, Ea, golden rgb, Ec, functional colour upper
        bound, may be visible)``, in the plan's order."""
        for step in self.plan.steps():
            if not step.rays.size:
                continue
            v, e = self.sample(step.zyx)
            golden, lo, hi = self.classified(v, e)
            k = np.asarray(step.dt, dtype=np.float64) / self.ref
            a, a_lo, a_hi = self.corrected(golden[:, 3], lo[:, 3], hi[:, 3], k)
            rgb, c_lo, c_hi = golden[:, :3], lo[:, :3], hi[:, :3]
            if self.lit:
                g, dg = self.gradient(step.zyx)
                view = step.view
                rgb, c_lo, c_hi = self.shaded(rgb, c_lo, c_hi, g, dg, view, self._viewer_q(step))
            ea = np.maximum(a_hi - a, a - a_lo)
            ec = np.maximum(c_hi - rgb, rgb - c_lo)
            yield step.rays, a, ea, rgb, ec, c_hi, a_hi > 0

    def _composite(self) -> np.ndarray:
        """Along each ray, golden samples in front of ``j`` and functional ones behind:
        swapping sample ``j`` changes the pixel by ``T_j [a_j (c_j - c'_j) + (a'_j -
        a_j)(c'_j - B_j)]`` with ``T_j`` golden's transmittance in front of ``j`` and
        ``B_j`` the functional premultiplied colour behind it (``0 <= B_j <= max_{k > j}
        c'_k``); summed over ``j`` this telescopes to golden minus functional in exact
        arithmetic.  Then the compositor's own roundings and the output rounding."""
        n = self.plan.n_rays
        steps = list(self._samples())
        if self.plan.back_to_front:
            steps = steps[::-1]  # the bound's sums run front to back
        t = np.ones(n)
        bound = np.zeros((n, 4))
        visible = np.zeros(n)
        tea = []
        for rays, a, ea, _, ec, _, vis in steps:
            tr = t[rays]
            bound[rays, :3] += (tr * a)[:, None] * ec
            bound[rays, 3] += tr * ea
            tea.append(tr * ea)
            visible[rays] += vis
            t[rays] = tr * (1.0 - a)
        behind = np.zeros((n, 3))
        for (rays, *_, c_hi, _), w in zip(steps[::-1], tea[::-1], strict=True):
            behind[rays] = np.maximum(behind[rays], np.minimum(c_hi, 1.0))
            bound[rays, :3] += w[:, None] * behind[rays]
        h = 2.0 ** -(self.dp.composite.acc_frac_bits + 1)
        if self.plan.back_to_front:  # one rounding of a convex combination per sample
            bound += (visible * h)[:, None]
        else:  # w = round((1 - A) a) and round(w c) per visible sample
            bound[:, :3] += (2 * visible * h)[:, None]
            bound[:, 3] += visible * h
        return bound + 0.5 / ((1 << self.dp.composite.output_bits) - 1)

    def _extreme(self) -> np.ndarray:
        """MIP / MinIP: ``|max s' - max s| <= max |s' - s|`` per ray, in volume units."""
        worst = np.zeros(self.plan.n_rays)
        for step in self.plan.steps():
            if step.rays.size:
                _, e = self.sample(step.zyx)
                worst[step.rays] = np.maximum(worst[step.rays], e)
        return worst * self.scale

    def _xray(self) -> np.ndarray:
        """``sum v dt``: the functional rung sums ``s' q(dt)`` (``q``: UQ8.F) exactly and
        adds ``offset sum q(dt)``; golden sums ``(offset + scale s) dt``."""
        frac = self.dp.composite.xray_frac_bits
        total = np.zeros(self.plan.n_rays)
        for step in self.plan.steps():
            if step.rays.size:
                v, e = self.sample(step.zyx)
                dt = np.broadcast_to(np.asarray(step.dt, dtype=np.float64), v.shape)
                dq = _q(dt, frac)
                err = self.scale * (e * dq + np.abs(v) * np.abs(dq - dt))
                total[step.rays] += err + abs(self.offset) * np.abs(dq - dt)
        return total

    def _iso(self) -> np.ndarray:
        """A ray whose first hit is the same sample on both sides (every earlier sample
        below the threshold by more than its error, the hit above it by more) differs by
        the shading of that sample; any other ray by at most 1."""
        n = self.plan.n_rays
        iso = self.scene.render.iso_value
        if iso is None:
            iso = 0.5 * sum(self.volume.value_range)
        thr_g = (iso - self.offset) / self.scale
        thr_f = np.ceil(thr_g * 2.0**self.S) / 2.0**self.S  # the functional's threshold
        done = np.zeros(n, dtype=bool)
        certain = np.ones(n, dtype=bool)
        bound = np.ones((n, 4))
        colour = np.asarray(self.scene.render.iso_color, dtype=np.float64)
        colour_q = np.round(colour * ONE12) / ONE12
        for step in self.plan.steps():
            live = ~done[step.rays]
            if not live.any():
                continue
            rays, zyx = step.rays[live], step.zyx[live]
            v, e = self.sample(zyx)
            hit = v >= thr_g
            sure_miss = (v + e < thr_f) & ~hit
            sure_hit = (v - e >= thr_f) & hit
            certain[rays] &= sure_miss | sure_hit
            hits = np.flatnonzero(hit)
            if hits.size:
                r = rays[hits]
                done[r] = True
                ok = certain[r]
                rgb = np.broadcast_to(colour, (hits.size, 3))
                q = np.broadcast_to(colour_q, (hits.size, 3))
                if self.lit:
                    g, dg = self.gradient(zyx[hits])
                    view = step.view if step.view.ndim == 1 else step.view[live][hits]
                    vq = self.plan.toward_viewer(r)
                    gold, f_lo, f_hi = self.shaded(rgb, q, q, g, dg, view, vq)
                else:
                    gold, f_lo, f_hi = rgb, q, q
                ec = np.maximum(f_hi - gold, gold - f_lo)
                out = 0.5 / ((1 << self.dp.composite.output_bits) - 1)
                bound[r[ok], :3] = ec[ok] + out
                bound[r[ok], 3] = 0.0
        # Rays golden never hit: certain ones stay empty on both sides.
        never = ~done & certain
        bound[never] = 0.0
        return bound


# ------------------------------------------------------------------------------ helpers


def _voxel_differences(raw: np.ndarray) -> list[np.ndarray]:
    """``[dx, dy, dz]`` central differences at voxels (``2 h`` times the derivative, raw
    units): ``v[i+1] - v[i-1]``, ``2 (v[1] - v[0])`` at the faces, 0 on a 1-voxel axis."""
    out = []
    for axis in (2, 1, 0):
        n = raw.shape[axis]
        d = np.zeros_like(raw)
        if n >= 2:
            v = np.moveaxis(raw, axis, 0)
            dv = np.moveaxis(d, axis, 0)
            dv[1:-1] = v[2:] - v[:-2]
            dv[0] = 2 * (v[1] - v[0])
            dv[-1] = 2 * (v[-1] - v[-2])
        out.append(d)
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    if v.ndim == 1:
        n = float(np.linalg.norm(v))
        return v / n if n > 1e-12 else np.zeros(3)
    return _unit_rows(v)


def _unit_rows(v: np.ndarray) -> np.ndarray:
    n = _norm(v)[:, None]
    return np.divide(v, n, out=np.zeros_like(v), where=n > 1e-12)


def _norm(v: np.ndarray):
    v = np.asarray(v, dtype=np.float64)
    return np.sqrt(np.sum(v * v, axis=-1))


def _rowdot(n: np.ndarray, v: np.ndarray) -> np.ndarray:
    v = np.broadcast_to(v, n.shape)
    return np.sum(n * v, axis=1)


def _power(x, n: float):
    """``x**n`` for ``x`` in [0, 1] with ``0**n = 0`` for ``n > 0``."""
    return np.power(np.asarray(x, dtype=np.float64), n)
