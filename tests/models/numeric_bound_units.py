"""Per-sample bounds of each unit of the datapath (numeric_bound.py's derivation,
docs/numerics.md): the interpolator (fixed-point lerps with quantised weights), the
classification LUT and the opacity-correction table, the gradient (central differences
at voxels or at samples) and the shader (Phong or reflectance maps).  Each gives the
golden value and an interval, or an error bound, for the functional rung's value;
:class:`numeric_bound_rays.Bound` composes them along rays."""

from __future__ import annotations

import numpy as np
from numeric_bound_maps import (
    ONE12,
    SQRT3,
    _chord,
    _half_lsb,
    _norm,
    _power,
    _q,
    _round,
    _rowdot,
    _tf_range,
    _unit,
    _unit_rows,
    _unorm_to_uq12,
    _voxel_differences,
    _voxel_map,
)

from hwsim.golden.shading import cube_face
from hwsim.spec.scene import Light
from models.datapath import Datapath


class _Field:
    """A per-voxel field (golden units: raw voxel units, float64) sampled as the
    interpolator samples it, with the per-axis spreads of each cell."""

    def __init__(self, data: np.ndarray, conv: float) -> None:
        self.flat = np.ascontiguousarray(data, dtype=np.float64).ravel()
        self.conv = conv  # per-voxel conversion error of the functional rung's copy


class SampleBound:
    """One frame's inputs and formats, and the bound of each unit on one batch of samples
    (positions ``zyx (n, 3)``)."""

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
