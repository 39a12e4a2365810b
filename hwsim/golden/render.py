"""The float64 golden renderer: iterate a sample plan, sample, classify, shade, composite.

# Ref: Levoy, "Display of Surfaces from Volume Data", IEEE CG&A 1988 (front-to-back
#      compositing of classified, shaded samples); design.md section 4.

Front-to-back compositing with premultiplied accumulation::

    a' = 1 - (1 - a) ** (dt / min(spacing))      opacity correction
    C += (1 - A) a' c;   A += (1 - A) a'

A ray stops once ``A >= early_termination`` (1.0 disables it).  mip / minip keep the
largest / smallest interpolated value (volume units; rays with no sample hold the
volume's minimum / maximum); xray sums ``value * dt`` (world units; 0 without samples);
iso shades the first sample whose value reaches ``iso_value``.  Samples whose opacity is
zero skip gradient and shading work; that never changes the image.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hwsim.golden.camera import index_to_world
from hwsim.golden.positions import SamplePlan, Step, make_plan
from hwsim.golden.sampling import Taps, sample, sample_gradients, taps, voxel_gradients
from hwsim.golden.shading import crop_keep, cut_factor, phong
from hwsim.scene import Scene
from hwsim.transfer import TransferFunction
from hwsim.volumes.volume import Volume

__all__ = ["GoldenResult", "render_golden"]

#: Per-volume derived arrays (float64 copy, voxel gradients), kept while the volume lives,
#: so successive frames of one volume do not recompute them (as VTK's mapper does not).
_DERIVED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _derived(volume: Volume, key: str, make: Callable[[], object]):
    cache = _DERIVED.setdefault(volume, {})
    if key not in cache:
        cache[key] = make()
    return cache[key]


@dataclass(frozen=True)
class GoldenResult:
    """A golden render: ``image`` is ``(H, W, 4)`` premultiplied RGBA (composite, iso) or
    ``(H, W)`` (mip, minip, xray), float64; ``samples`` evaluated; ``rays`` that took at
    least one sample."""

    image: np.ndarray
    samples: int
    rays: int
    plan: SamplePlan


class _Renderer:
    def __init__(
        self, scene: Scene, volume: Volume, transfer: TransferFunction, plan: SamplePlan
    ) -> None:
        self.scene, self.volume, self.transfer, self.plan = scene, volume, transfer, plan
        self.mode = scene.render.mode
        self.kind = scene.render.interpolation
        self.flat = _derived(
            volume, "flat", lambda: np.ascontiguousarray(volume.data, dtype=np.float64).ravel()
        )
        self.ref = min(volume.spacing)
        self.lights = [
            (plan.camera.light_to_world(light.direction, light.space), light.intensity)
            for light in scene.lights
        ]
        composite = self.mode == "composite"
        self.need_grad = scene.lit or (composite and transfer.modulates)
        self.grads = None
        if self.need_grad and scene.render.gradient == "voxel":
            self.grads = _derived(
                volume, "grads", lambda: voxel_gradients(volume.data, volume.spacing)
            )
        self.pre = None
        if composite and transfer.order == "pre":
            rgba = transfer.classify(self.flat)
            self.pre = [np.ascontiguousarray(rgba[:, c]) for c in range(4)]

    def gradient(self, t: Taps, zyx: np.ndarray) -> np.ndarray:
        if self.grads is not None:
            return np.stack([sample(g, t) for g in self.grads], axis=1)
        return sample_gradients(self.flat, zyx, self.volume.shape, self.volume.spacing, self.kind)

    def mask(self, step: Step) -> tuple[Step, np.ndarray | None]:
        """Apply crop (drop samples) and cut planes (a factor per sample)."""
        keep = None
        if self.scene.crop is not None:
            keep = crop_keep(step.zyx, self.scene.crop)
        factor = None
        if self.scene.cut_planes:
            factor = cut_factor(index_to_world(step.zyx, self.volume), self.scene.cut_planes)
            keep = factor > 0 if keep is None else keep & (factor > 0)
        if keep is not None:
            step = _subset(step, keep)
            factor = factor[keep] if factor is not None else None
        return step, factor

    def run(self, progress: Callable[[int, int], None] | None) -> GoldenResult:
        plan, mode = self.plan, self.mode
        n = plan.n_rays
        lo, hi = self.volume.value_range
        if mode in ("composite", "iso"):
            acc = np.zeros((n, 4))
        elif mode == "mip":
            acc = np.full(n, -np.inf)
        elif mode == "minip":
            acc = np.full(n, np.inf)
        else:
            acc = np.zeros(n)
        alive = np.ones(n, dtype=bool)
        touched = np.zeros(n, dtype=bool)
        ert = self.scene.render.early_termination
        iso = self.scene.render.iso_value
        iso = 0.5 * (lo + hi) if iso is None else iso
        samples = 0
        for j, step in enumerate(plan.steps()):
            if mode in ("composite", "iso"):
                step = _subset(step, alive[step.rays])
            step, factor = self.mask(step)
            if step.rays.size:
                samples += step.rays.size
                touched[step.rays] = True
                t = taps(step.zyx, self.volume.shape, self.kind)
                if mode == "composite":
                    self.composite(step, t, factor, acc, alive, ert)
                elif mode == "iso":
                    self.iso(step, t, iso, acc, alive)
                else:
                    v = sample(self.flat, t)
                    if mode == "mip":
                        _max_into(acc, step.rays, v)
                    elif mode == "minip":
                        _min_into(acc, step.rays, v)
                    else:
                        w = v * step.dt if factor is None else v * factor * step.dt
                        acc[step.rays] += w
            if progress is not None:
                progress(j + 1, plan.n_steps)
        background = {"mip": lo, "minip": hi}.get(mode, 0.0)
        if mode in ("mip", "minip"):
            acc[~touched] = background
        image = plan.to_image(acc, background)
        return GoldenResult(image, samples, int(touched.sum()), plan)

    def composite(self, step: Step, t: Taps, factor, acc, alive, ert: float) -> None:
        if self.pre is not None:
            a = sample(self.pre[3], t)
        else:
            v = sample(self.flat, t)
            a = self.transfer.opacity(v)
        if factor is not None:
            a = a * factor
        vis = a > 0
        if not vis.any():
            return
        rays, a = step.rays[vis], a[vis]
        tv = Taps(t.idx[:, vis], t.w[:, vis])
        if self.pre is not None:
            rgb = np.stack([sample(self.pre[c], tv) for c in range(3)], axis=1)
        else:
            rgb = self.transfer.classify(v[vis])[:, :3]
        if self.need_grad:
            g = self.gradient(tv, step.zyx[vis])
            if self.transfer.modulates:
                a = a * self.transfer.gradient_factor(np.linalg.norm(g, axis=1))
            if self.scene.lit:
                rgb = phong(rgb, g, self.lights, self.plan.toward_viewer(rays), self.scene.material)
        dt = step.dt if np.isscalar(step.dt) else step.dt[vis]
        a = 1.0 - (1.0 - a) ** (dt / self.ref)
        weight = (1.0 - acc[rays, 3]) * a
        acc[rays, :3] += weight[:, None] * rgb
        acc[rays, 3] += weight
        if ert < 1.0:
            alive[rays] = acc[rays, 3] < ert

    def iso(self, step: Step, t: Taps, iso: float, acc, alive) -> None:
        v = sample(self.flat, t)
        hit = v >= iso
        if not hit.any():
            return
        rays = step.rays[hit]
        rgb = np.broadcast_to(np.asarray(self.scene.render.iso_color), (rays.size, 3))
        if self.scene.lit:
            g = self.gradient(Taps(t.idx[:, hit], t.w[:, hit]), step.zyx[hit])
            rgb = phong(rgb, g, self.lights, self.plan.toward_viewer(rays), self.scene.material)
        acc[rays, :3] = rgb
        acc[rays, 3] = 1.0
        alive[rays] = False


def _subset(step: Step, keep: np.ndarray) -> Step:
    if keep.all():
        return step
    dt = step.dt if np.isscalar(step.dt) else step.dt[keep]
    return Step(step.rays[keep], step.zyx[keep], dt)


def _max_into(acc: np.ndarray, rays: np.ndarray, v: np.ndarray) -> None:
    acc[rays] = np.maximum(acc[rays], v)  # a ray appears at most once per step


def _min_into(acc: np.ndarray, rays: np.ndarray, v: np.ndarray) -> None:
    acc[rays] = np.minimum(acc[rays], v)


def render_golden(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    *,
    sampling: str = "ray",
    progress: Callable[[int, int], None] | None = None,
) -> GoldenResult:
    """Render ``scene`` on ``volume`` in float64.

    Parameters
    ----------
    scene : Scene
        View, lights, material and render settings (``scene.volume`` is not read).
    volume : Volume
        The data, ``(z, y, x)``.
    transfer : TransferFunction
        Classification (used by composite mode).
    sampling : str
        Sample positions: "ray" (ideal), "shear-warp", "shear-image", "slice-parallel".
    progress : callable, optional
        ``progress(done_steps, total_steps)``.

    Returns
    -------
    GoldenResult
    """
    plan = make_plan(scene, volume, sampling)
    return _Renderer(scene, volume, transfer, plan).run(progress)
