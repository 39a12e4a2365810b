"""The float64 golden renderer: iterate a sample plan, sample, classify, shade, composite.

# Ref: Levoy, "Display of Surfaces from Volume Data", IEEE CG&A 1988 (front-to-back
#      compositing of classified, shaded samples); design.md section 4.

Front-to-back compositing with premultiplied accumulation::

    a' = 1 - (1 - a) ** (dt / min(spacing))      opacity correction
    C += (1 - A) a' c;   A += (1 - A) a'

A ray stops once ``A >= early_termination`` (1.0 disables it).  mip / minip keep the
largest / smallest interpolated value (volume units; rays with no sample hold the
volume's minimum / maximum); xray sums ``value * dt`` (world units; 0 without samples);
iso shades the first sample whose value reaches ``iso_value``.  Composite and iso rays
leap over blocks that cannot be visible (:mod:`hwsim.golden.occupancy`), and samples of
zero opacity skip gradient and shading work; neither changes the image by a bit.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.golden import geometry as geo
from hwsim.golden import occupancy as occ
from hwsim.golden import raywalk
from hwsim.golden.camera import index_to_world
from hwsim.golden.classification import FloatClassifier
from hwsim.golden.cursor import blend_cursor, cursor_parts
from hwsim.golden.positions import SamplePlan, Step, make_plan
from hwsim.golden.power import power
from hwsim.golden.sampling import interleave, sample, sample_gradients, taps, trilinear_rows
from hwsim.golden.shading import crop_keep, cut_factor, magnitude, phong
from hwsim.spec.scene import Scene
from hwsim.spec.scene_features import VALUE_FIELD, check_features
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes.volume import Volume

__all__ = ["GoldenResult", "render_golden"]

#: Per-volume derived arrays (float64 values, interleaved value + voxel gradient rows,
#: block value ranges), kept while the volume lives so successive frames of one volume
#: do not recompute them (as VTK's mapper keeps its gradients).
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
    least one sample; the ``plan`` whose positions were used."""

    image: np.ndarray
    samples: int
    rays: int
    plan: SamplePlan


def occupancy_for(scene: Scene, volume: Volume, transfer: TransferFunction):
    """The :class:`~hwsim.golden.occupancy.Occupancy` of a composite or iso render, or
    None where leaping does not apply (other modes, cubic filtering)."""
    mode = scene.render.mode
    if mode not in ("composite", "iso") or scene.render.interpolation == "cubic":
        return None
    if scene.classification is not None:
        return None  # combined opacity: no per-block bound from one function; no leaping
    if scene.cursor is not None:
        return None  # the cursor is drawn over transparent samples too
    lo, hi = _derived(volume, "blocks", lambda: occ.block_ranges(volume.data))
    if mode == "iso":
        v_lo, v_hi = volume.value_range
        iso = scene.render.iso_value
        occupied = hi >= (0.5 * (v_lo + v_hi) if iso is None else iso)
    else:
        occupied = occ.opacity_can_be_positive(lo, hi, transfer.values, transfer.rgba[:, 3])
    return occ.occupancy_from_ranges(occupied)


class _Renderer:
    def __init__(
        self,
        scene: Scene,
        volume: Volume,
        transfer: TransferFunction,
        plan: SamplePlan,
        reflectance_map: int | None = None,
        compiled: bool = True,
    ) -> None:
        self.compiled = compiled
        self.scene, self.volume, self.transfer, self.plan = scene, volume, transfer, plan
        self.reflectance_map = reflectance_map
        self.mode = scene.render.mode
        self.kind = scene.render.interpolation
        self.ref = min(volume.spacing)
        self.lights = [
            (plan.camera.light_to_world(light.direction, light.space), light.intensity)
            for light in scene.lights
        ]
        composite = self.mode == "composite"
        self.need_grad = scene.lit or (composite and transfer.modulates)
        self.rows = None  # (N, 4) value and voxel gradient, interleaved
        if self.need_grad and scene.render.gradient in ("voxel", None):
            self.rows = _derived(volume, "rows", lambda: interleave(volume.data, volume.spacing))
            self.flat = self.rows[:, 0]
        else:
            self.flat = _derived(
                volume, "flat", lambda: np.ascontiguousarray(volume.data, np.float64).ravel()
            )
        self.classifier = None
        if scene.classification is not None:
            self.classifier = FloatClassifier(scene, volume, scene.base_dir)
        self.pre = None
        if composite and transfer.order == "pre":
            if self.classifier is not None:
                self.pre = self.classifier.classify(
                    {VALUE_FIELD: self.flat, **self.classifier.flat_fields}
                )
            else:
                self.pre = transfer.classify(self.flat)  # (N, 4): classified voxels
        self.geometry = None
        self.stopped: np.ndarray | None = None  # rays the depth test ended this step
        if scene.geometry is not None:
            self.distance = scene.view.distance
            self.geometry = geo.rasterise(
                scene.geometry, plan.camera, self.distance, scene.base_dir
            )

    def values(self, zyx: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Interpolated values ``(n,)`` and, with voxel gradients, gradients ``(n, 3)``."""
        if self.kind == "trilinear":
            if self.rows is not None:
                s = trilinear_rows(self.rows, self.volume.shape, zyx)
                return s[:, 0], s[:, 1:]
            return trilinear_rows(self.flat, self.volume.shape, zyx), None
        t = taps(zyx, self.volume.shape, self.kind)
        g = None
        if self.rows is not None:
            g = np.stack([sample(self.rows[:, c], t) for c in (1, 2, 3)], axis=1)
        return sample(self.flat, t), g

    def filtered(self, field: np.ndarray, zyx: np.ndarray) -> np.ndarray:
        """Any per-voxel rows ``(N, C)`` filtered at ``zyx``: ``(n, C)``."""
        if self.kind == "trilinear":
            return trilinear_rows(field, self.volume.shape, zyx)
        t = taps(zyx, self.volume.shape, self.kind)
        return np.stack([sample(np.ascontiguousarray(field[:, c]), t) for c in range(4)], 1)

    def sample_gradient(self, zyx: np.ndarray) -> np.ndarray:
        v = self.volume
        return sample_gradients(self.flat, zyx, v.shape, v.spacing, self.kind)

    def mask(self, step: Step) -> tuple[Step, np.ndarray | None]:
        """Apply crop (drop samples) and cut planes (a factor per sample)."""
        keep = None
        if self.scene.crop is not None:
            keep = crop_keep(step.zyx, self.scene.crop)
        factor = None
        if self.scene.cut_planes:
            factor = cut_factor(index_to_world(step.zyx, self.volume), self.scene.cut_planes)
            keep = factor > 0 if keep is None else keep & (factor > 0)
        if self.geometry is not None:
            test = self.scene.geometry.depth_test  # type: ignore[union-attr]
            passed = geo.depth_pass(
                test,
                geo.sample_depth(step.zyx, self.plan.camera, self.volume, self.distance),
                self.geometry.depth[step.rays],
            )
            if test in geo.STOPPING_TESTS and not self.plan.back_to_front:
                self.stopped = step.rays[~passed]
            keep = passed if keep is None else keep & passed
        cursor = self.scene.cursor
        if keep is not None and cursor is not None and cursor.disable_crop:
            keep |= cursor_parts(step.zyx, cursor) >= 0  # drawn where the volume is cut
        if keep is not None:
            step = _subset(step, keep)
            factor = factor[keep] if factor is not None else None
        return step, factor

    def classified(self, v: np.ndarray, zyx: np.ndarray) -> np.ndarray:
        """Multi-LUT RGBA ``(n, 4)`` of samples with values ``v`` at ``zyx``."""
        inputs = {VALUE_FIELD: v}
        for name, flat in self.classifier.flat_fields.items():  # type: ignore[union-attr]
            inputs[name] = self.filtered_1(flat, zyx)
        return self.classifier.classify(inputs)  # type: ignore[union-attr]

    def filtered_1(self, flat: np.ndarray, zyx: np.ndarray) -> np.ndarray:
        """One raveled per-voxel array filtered at ``zyx``: ``(n,)``."""
        if self.kind == "trilinear":
            return trilinear_rows(flat, self.volume.shape, zyx)
        return sample(flat, taps(zyx, self.volume.shape, self.kind))

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
        feedback = alive if mode in ("composite", "iso") else None
        if self.compiled and raywalk.eligible(self):  # the same operations, a whole ray at a time
            acc, samples, rays = raywalk.walk(self, progress)
            return GoldenResult(plan.to_image(acc), samples, rays, plan)
        for j, step in enumerate(plan.steps(feedback)):
            step, factor = self.mask(step)
            if self.stopped is not None:  # embedded geometry ends these rays
                alive[self.stopped] = False
                self.stopped = None
            if step.rays.size:
                samples += step.rays.size
                touched[step.rays] = True
                if mode == "composite":
                    self.composite(step, factor, acc, alive, ert)
                elif mode == "iso":
                    self.iso(step, iso, acc, alive)
                else:
                    v = self.values(step.zyx)[0]
                    if mode == "mip":
                        acc[step.rays] = np.maximum(acc[step.rays], v)  # once per step
                    elif mode == "minip":
                        acc[step.rays] = np.minimum(acc[step.rays], v)
                    else:
                        w = v * step.dt if factor is None else v * factor * step.dt
                        acc[step.rays] += w
            if progress is not None:
                progress(j + 1, plan.n_steps)
        if self.geometry is not None:
            geo.blend_behind(acc, self.geometry.rgba)
        background = {"mip": lo, "minip": hi}.get(mode, 0.0)
        if mode in ("mip", "minip"):
            acc[~touched] = background
        image = plan.to_image(acc, background)
        return GoldenResult(image, samples, int(touched.sum()), plan)

    def composite(self, step: Step, factor, acc, alive, ert: float) -> None:
        zyx = step.zyx
        if self.pre is not None:
            rgba = self.filtered(self.pre, zyx)
            a, g = rgba[:, 3], None
        elif self.classifier is not None:
            v, g = self.values(zyx)
            rgba = self.classified(v, zyx)
            a = rgba[:, 3]
        else:
            v, g = self.values(zyx)
            a = self.transfer.opacity(v)
        if factor is not None:
            a = a * factor
        cursor = self.scene.cursor
        part = cursor_parts(zyx, cursor) if cursor is not None else None
        vis = np.flatnonzero(a > 0 if part is None else (a > 0) | (part >= 0))
        if vis.size == 0:
            return
        rays, a, zyx = step.rays[vis], a[vis], zyx[vis]
        if self.pre is not None or self.classifier is not None:
            rgb = rgba[vis, :3]
        else:
            rgb = self.transfer.classify(v[vis])[:, :3]
        if self.need_grad:
            if self.rows is None:
                g = self.sample_gradient(zyx)
            elif g is None:
                g = self.values(zyx)[1]
            else:
                g = g[vis]
            if self.transfer.modulates:
                a = a * self.transfer.gradient_factor(magnitude(g))
            if self.scene.lit:
                view = _view(step, vis)
                illum = None
                if self.transfer.modulates_illumination:
                    illum = self.transfer.illumination_factor(magnitude(g))
                rgb = phong(
                    rgb, g, self.lights, view, self.scene.material, self.reflectance_map, illum
                )
        if part is not None:
            rgb, a = blend_cursor(rgb, a, part[vis], cursor)  # type: ignore[arg-type]
        dt = step.dt if np.isscalar(step.dt) else step.dt[vis]
        a = 1.0 - power(1.0 - a, dt / self.ref)
        if self.plan.back_to_front:  # samples farthest first: C = a c + (1 - a) C
            acc[rays, :3] = a[:, None] * rgb + (1.0 - a)[:, None] * acc[rays, :3]
            acc[rays, 3] = a + (1.0 - a) * acc[rays, 3]
            return
        weight = (1.0 - acc[rays, 3]) * a
        acc[rays, :3] += weight[:, None] * rgb
        acc[rays, 3] += weight
        if ert < 1.0:
            alive[rays] = acc[rays, 3] < ert

    def iso(self, step: Step, iso: float, acc, alive) -> None:
        v, g = self.values(step.zyx)
        hit = np.flatnonzero(v >= iso)
        if hit.size == 0:
            return
        rays = step.rays[hit]
        rgb = np.broadcast_to(np.asarray(self.scene.render.iso_color), (rays.size, 3))
        if self.scene.lit:
            g = self.sample_gradient(step.zyx[hit]) if self.rows is None else g[hit]
            view = _view(step, hit)
            rgb = phong(rgb, g, self.lights, view, self.scene.material, self.reflectance_map)
        acc[rays, :3] = rgb
        acc[rays, 3] = 1.0
        alive[rays] = False


def _view(step: Step, sel: np.ndarray) -> np.ndarray:
    return step.view if step.view.ndim == 1 else step.view[sel]


def _subset(step: Step, keep: np.ndarray) -> Step:
    if keep.all():
        return step
    dt = step.dt if np.isscalar(step.dt) else step.dt[keep]
    view = step.view if step.view is None or step.view.ndim == 1 else step.view[keep]
    return Step(step.rays[keep], step.zyx[keep], dt, view)


def render_golden(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    *,
    sampling: str = "ray",
    progress: Callable[[int, int], None] | None = None,
    leap: bool = True,
    reflectance_map: int | None = None,
    compiled: bool = True,
) -> GoldenResult:
    """Render ``scene`` on ``volume`` in float64.

    Parameters
    ----------
    scene : Scene
        View, lights, material and render settings (``scene.volume`` is not read).
    volume : Volume
        The data, ``(z, y, x)``, voxel centres at integer index coordinates.
    transfer : TransferFunction
        Classification (used by composite mode).
    sampling : str
        Sample positions: "ray" (ideal), "shear-warp", "shear-image", "slice-parallel".
    progress : callable, optional
        ``progress(done_steps, total_steps)`` after every plan step.
    leap : bool
        Leap over blocks that cannot be visible (composite, iso; never changes the
        image, only ``samples`` and speed).  False plans every sample in the box.
    reflectance_map : int, optional
        Shade as a machine's reflectance maps do: Phong at the centre of each normal's
        cell in a cube map of this many cells per face edge (VolumePro 500).

    Returns
    -------
    GoldenResult
        float64 image, sample and ray counts, and the plan.
    """
    check_features(scene)
    if scene.geometry is not None and sampling in ("shear-warp", "slice-parallel"):
        raise InputError(
            "embedded geometry needs rays through image pixels",
            source=scene.source,
            key="geometry",
            allowed="sampling ray or shear-image",
        )
    occupancy = occupancy_for(scene, volume, transfer) if leap else None
    plan = make_plan(scene, volume, sampling, occupancy=occupancy)
    return _Renderer(scene, volume, transfer, plan, reflectance_map, compiled).run(progress)
