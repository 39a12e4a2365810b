"""The ``functional`` rung: the bit-exact fixed-point datapath, vectorised over each step.

# Ref: design.md section 3 (functional rung); architectures.md section 9 (units).

It iterates the same :class:`hwsim.golden.SamplePlan` as the golden renderer, so golden
at an architecture's sample positions and functional differ only numerically.  Every
value after voxel conversion is an integer in a named format of ``models.units``; the
only float operations are host-side set-up (LUT, light vectors, correction tables) and
the final 2-D warp, which the VolumePro 500 host also does in floating point.

Timing is a closed-form estimate: each slice (or ray step) costs
``ceil(samples / pipelines) + slice_overhead_cycles`` cycles, plus
``section_overhead_cycles`` per section and the pipeline fill latency once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.arch import ArchConfig
from hwsim.golden.camera import index_to_world
from hwsim.golden.positions import SamplePlan, Step
from hwsim.numerics import SATURATIONS
from hwsim.scene import Scene
from hwsim.transfer import TransferFunction
from hwsim.volumes.volume import Volume
from models.datapath import Datapath
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import crop as crop_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units import shade as shade_unit
from models.units.voxel import convert_volume

__all__ = ["FunctionalResult", "render_functional", "pipeline_latency"]

ONE = 1 << 12  # 1.0 in UQ1.12


def pipeline_latency(scene: Scene) -> int:
    """Cycles from a voxel read to its sample's composite, for the units the scene uses."""
    units = [interp_unit, composite_unit]
    if scene.render.mode == "composite":
        units.append(classify_unit)
    if scene.lit:
        units += [gradient_unit, shade_unit]
    return int(sum(u.LATENCY for u in units))


@dataclass
class FunctionalResult:
    """Image (same layout as golden), samples, the cycle estimate and raw counters."""

    image: np.ndarray
    samples: int
    rays: int
    cycles: int
    counters: dict[str, Any] = field(default_factory=dict)


class _Functional:
    def __init__(
        self,
        scene: Scene,
        volume: Volume,
        transfer: TransferFunction,
        arch: ArchConfig,
        plan: SamplePlan,
        datapath: Datapath,
    ) -> None:
        self.scene, self.volume, self.transfer, self.arch, self.plan = (
            scene,
            volume,
            transfer,
            arch,
            plan,
        )
        self.dp = dp = datapath
        self.mode = scene.render.mode
        self.raw, self.vmap = convert_volume(volume, dp.voxel_bits)
        self.flat = self.raw.ravel()
        self.S = dp.interp.sample_frac_bits
        self.ref = min(volume.spacing)
        composite = self.mode == "composite"
        self.need_grad = scene.lit or (composite and transfer.modulates)
        if composite or self.mode == "iso":
            self.lut = classify_unit.build_lut(
                transfer, self.vmap.to_value, dp.voxel_bits, dp.classify
            )
        self.pre = None
        if composite and transfer.order == "pre":
            self.pre = classify_unit.classify_voxels(self.raw, self.lut, dp.voxel_bits, dp.classify)
        self.diffs = None
        if self.need_grad and dp.gradient.source == "voxel":
            self.diffs = gradient_unit.voxel_differences(self.raw)
        if self.need_grad and transfer.modulates:
            # Largest |gradient| the data can have, in value units per world unit.
            span = float(self.raw.max() - self.raw.min()) * self.vmap.scale
            self.gm_max = np.sqrt(3.0) * span / self.ref
            self.gm_table = classify_unit.build_gm_table(transfer, self.gm_max, dp.classify)
            # An integer magnitude m stands for m * scale / (2 * 2**S * min spacing).
            per_unit = self.vmap.scale / (2.0 * (1 << self.S) * self.ref)
            self.gm_scale = classify_unit.gm_scale(per_unit, self.gm_max, dp.classify)
        if scene.lit:
            lights = [
                (plan.camera.light_to_world(light.direction, light.space), light.intensity)
                for light in scene.lights
            ]
            m = scene.material
            material = (m.ambient, m.diffuse, m.specular, m.shininess)
            view = plan.camera.toward_viewer
            self.shader = None
            if view.ndim == 1 or plan.kind == "shear-warp":
                self.shader = shade_unit.setup(lights, -plan.camera.d, material, dp.shade)
            else:
                self.lights, self.material = lights, material
        self.iso_rgb = np.round(np.asarray(scene.render.iso_color) * ONE).astype(np.int64)

    # ------------------------------------------------------------------ per step

    def gradient(self, t, zyx: np.ndarray) -> np.ndarray:
        if self.diffs is not None:
            g = np.stack(
                [interp_unit.interpolate(d, t, self.dp.interp) for d in self.diffs], axis=1
            )
        else:
            g = gradient_unit.sample_differences(self.flat, zyx, self.volume.shape, self.dp.interp)
        return gradient_unit.to_world(g, self.volume.spacing, self.S, self.dp.gradient)

    def shade(self, rgb: np.ndarray, g: np.ndarray, rays: np.ndarray) -> np.ndarray:
        normals = gradient_unit.normals(g, self.dp.gradient)
        if self.shader is not None:
            return shade_unit.shade(self.shader, rgb, normals)
        shader = shade_unit.setup(
            self.lights, self.plan.toward_viewer(rays), self.material, self.dp.shade
        )
        return shade_unit.shade(shader, rgb, normals)

    def gm_index(self, g: np.ndarray) -> np.ndarray:
        return classify_unit.gm_index(gradient_unit.magnitude(g), self.gm_scale, self.dp.classify)

    def masks(self, step: Step) -> tuple[Step, np.ndarray | None]:
        keep, factor = None, None
        if self.scene.crop is not None:
            keep = crop_unit.crop_keep(step.zyx, self.scene.crop)
        if self.scene.cut_planes:
            factor = crop_unit.cut_factor(
                index_to_world(step.zyx, self.volume),
                self.scene.cut_planes,
                crop_unit.CutConfig(max_planes=max(1, self.arch.cut_planes)),
            )
            keep = factor > 0 if keep is None else keep & (factor > 0)
        if keep is not None:
            step = _subset(step, keep)
            factor = factor[keep] if factor is not None else None
        return step, factor

    def run(self, progress: Callable[[int, int], None] | None) -> FunctionalResult:
        plan, mode, dp = self.plan, self.mode, self.dp
        n = plan.n_rays
        if mode in ("composite", "iso"):
            acc = np.zeros((n, 4), dtype=np.int64)
        elif mode == "mip":
            acc = np.full(n, -1, dtype=np.int64)
        elif mode == "minip":
            acc = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
        else:
            acc = np.zeros(n, dtype=np.int64)
            dt_sum = np.zeros(n, dtype=np.int64)
        alive = np.ones(n, dtype=bool)
        touched = np.zeros(n, dtype=bool)
        ert = self.scene.render.early_termination
        iso = self.scene.render.iso_value
        lo, hi = self.volume.value_range
        iso = 0.5 * (lo + hi) if iso is None else iso
        iso_raw = int(np.ceil((iso - self.vmap.offset) / self.vmap.scale * (1 << self.S)))
        samples = 0
        cycles = 0
        before = SATURATIONS.copy()
        P = self.arch.pipelines
        for j, step in enumerate(plan.steps()):
            cycles += -(-step.rays.size // P) + self.arch.slice_overhead_cycles
            if mode in ("composite", "iso"):
                step = _subset(step, alive[step.rays])
            step, factor = self.masks(step)
            if step.rays.size:
                samples += step.rays.size
                touched[step.rays] = True
                t = interp_unit.interp_taps(step.zyx, self.volume.shape, dp.interp)
                if mode == "composite":
                    self.composite(step, t, factor, acc, alive, ert)
                elif mode == "iso":
                    s = interp_unit.interpolate(self.flat, t, dp.interp)
                    hit = composite_unit.iso_hit(s, iso_raw)
                    if hit.any():
                        rays = step.rays[hit]
                        rgb = np.broadcast_to(self.iso_rgb, (rays.size, 3))
                        if self.scene.lit:
                            th = interp_unit.InterpTaps(t.idx[:, hit], t.frac[:, hit])
                            rgb = self.shade(rgb, self.gradient(th, step.zyx[hit]), rays)
                        acc[rays, :3] = rgb.astype(np.int64) << (dp.composite.acc_frac_bits - 12)
                        acc[rays, 3] = 1 << dp.composite.acc_frac_bits
                        alive[rays] = False
                else:
                    s = interp_unit.interpolate(self.flat, t, dp.interp)
                    if mode == "mip":
                        composite_unit.mip(acc, step.rays, s)
                    elif mode == "minip":
                        composite_unit.minip(acc, step.rays, s)
                    else:
                        if factor is not None:
                            s = (s * factor + (1 << 11)) >> 12
                        composite_unit.xray(acc, step.rays, s, step.dt, dp.composite)
                        composite_unit.xray(
                            dt_sum, step.rays, np.full(s.size, 1, np.int64), step.dt, dp.composite
                        )
            if progress is not None:
                progress(j + 1, plan.n_steps)
        sections = 0
        if self.arch.section_width and plan.shape[1] > 0:
            sections = -(-plan.shape[1] // self.arch.section_width)
        cycles += sections * self.arch.section_overhead_cycles + pipeline_latency(self.scene)
        image = self.finish(acc, touched, dt_sum if mode == "xray" else None)
        clipped = {k: v - before.get(k, 0) for k, v in SATURATIONS.items() if v - before.get(k, 0)}
        counters = {
            "functional.samples": samples,
            "functional.sections": sections,
            "functional.saturated": clipped,
        }
        return FunctionalResult(image, samples, int(touched.sum()), int(cycles), counters)

    def composite(self, step: Step, t, factor, acc, alive, ert: float) -> None:
        dp = self.dp
        if self.pre is not None:
            chans = [interp_unit.interpolate(c, t, dp.interp) for c in self.pre]
            alpha = (chans[3] + (1 << (self.S - 1))) >> self.S
        else:
            s = interp_unit.interpolate(self.flat, t, dp.interp)
            rgb, alpha = classify_unit.classify(s, self.lut, dp.voxel_bits, self.S, dp.classify)
        if factor is not None:
            alpha = (alpha * factor + (1 << 11)) >> 12
        vis = alpha > 0
        if not vis.any():
            return
        rays, alpha = step.rays[vis], alpha[vis]
        tv = interp_unit.InterpTaps(t.idx[:, vis], t.frac[:, vis])
        if self.pre is not None:
            rgb = np.stack([(c[vis] + (1 << (self.S - 1))) >> self.S for c in chans[:3]], axis=1)
        else:
            rgb = rgb[vis]
        if self.need_grad:
            g = self.gradient(tv, step.zyx[vis])
            if self.transfer.modulates:
                alpha = classify_unit.modulate(alpha, self.gm_index(g), self.gm_table)
            if self.scene.lit:
                rgb = self.shade(rgb, g, rays)
        dt = step.dt if np.isscalar(step.dt) else step.dt[vis]
        alpha = composite_unit.correct_opacity(alpha, np.asarray(dt) / self.ref, dp.composite)
        composite_unit.front_to_back(acc, rays, rgb, alpha, dp.composite)
        if ert < 1.0:
            alive[rays] = ~composite_unit.terminated(acc[rays], ert, dp.composite)

    def finish(self, acc: np.ndarray, touched: np.ndarray, dt_sum) -> np.ndarray:
        mode, plan, vmap = self.mode, self.plan, self.vmap
        lo, hi = self.volume.value_range
        if mode in ("composite", "iso"):
            out = composite_unit.to_output(acc, self.dp.composite)
            return plan.to_image(composite_unit.output_to_float(out, self.dp.composite), 0.0)
        if mode in ("mip", "minip"):
            values = vmap.offset + vmap.scale * acc.astype(np.float64) / (1 << self.S)
            values[~touched] = lo if mode == "mip" else hi
            return plan.to_image(values, lo if mode == "mip" else hi)
        scale = 1.0 / ((1 << self.S) * (1 << self.dp.composite.xray_frac_bits))
        dts = dt_sum.astype(np.float64) / (1 << self.dp.composite.xray_frac_bits)
        values = vmap.offset * dts + vmap.scale * acc.astype(np.float64) * scale
        return plan.to_image(values, 0.0)


def _subset(step: Step, keep: np.ndarray) -> Step:
    if keep.all():
        return step
    dt = step.dt if np.isscalar(step.dt) else step.dt[keep]
    return Step(step.rays[keep], step.zyx[keep], dt)


def render_functional(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    arch: ArchConfig,
    plan: SamplePlan,
    *,
    datapath: Datapath | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> FunctionalResult:
    """Render with the fixed-point units of ``arch`` at ``plan``'s sample positions."""
    if datapath is None:
        bits = volume.bits if volume.data.dtype.kind in "iu" else 0
        datapath = Datapath.from_arch(arch, bits)
    return _Functional(scene, volume, transfer, arch, plan, datapath).run(progress)
