"""Per-ray bounds of each mode (numeric_bound.py's derivation, docs/numerics.md):
compositing by the telescoping identity (front to back or back to front), MIP and MinIP,
X-ray sums and iso-surface first hits, over the per-sample unit bounds of
:class:`numeric_bound_units.SampleBound`."""

from __future__ import annotations

import numpy as np
from numeric_bound_maps import ONE12, _q
from numeric_bound_units import SampleBound


class Bound(SampleBound):
    """The bound of one frame, one value per pixel and channel (:meth:`run`)."""

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
