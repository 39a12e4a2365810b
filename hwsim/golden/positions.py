"""Sample positions: the ideal ray caster's and each architecture's processing order.

# Ref: Lacroute & Levoy, SIGGRAPH 1994 (shear-warp); Wu et al., I3D 2003 (shear-image);
#      Pfister & Kaufman, VolVis 1996 (Cube-4 slice-parallel); architectures.md section 6.

A :class:`SamplePlan` says *where* samples are taken and how the accumulated rays become
the final image; it knows nothing of classification or shading, so the float64 golden
renderer and the fixed-point renderers iterate the same plan and differ only in
arithmetic.  Kinds:

``ray``
    Rays through the image's pixel centres, samples every ``dt`` world units on a lattice
    shared by all rays (``t = k dt``; ``t = 0`` on the plane through the volume centre for
    parallel views, at the eye for perspective), kept where ``t_in <= t < t_out`` (entry
    and exit of the box; half-open, so no face is counted twice).
``shear-image`` (VolumePro 1000)
    Rays through the image's pixel centres, sampled where they cross the slice planes of
    the principal axis (voxel slices, plus ``1/supersampling`` sub-slices).
``shear-warp`` (VolumePro 500, EM-Cube; parallel only)
    Rays from the integer pixels of a base plane parallel to the slices (the front
    slice), sampled on every slice at a shear offset that is the same for the whole
    slice; the base-plane image is warped to the final image by bilinear resampling.
``slice-parallel`` (Cube-4)
    ``shear-warp`` for parallel views, ``shear-image`` for perspective.

The principal axis is the index axis with the largest ``|d / spacing|`` component (ties
go to z, then y, then x).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from hwsim.errors import InputError
from hwsim.golden.camera import Camera, world_to_index
from hwsim.scene import Scene
from hwsim.volumes.volume import Volume

__all__ = ["SAMPLINGS", "Step", "SamplePlan", "make_plan"]

SAMPLINGS = ("ray", "shear-warp", "shear-image", "slice-parallel")
_TINY = 1e-12


@dataclass(frozen=True)
class Step:
    """One front-to-back step: a sample for each listed ray.

    ``rays`` are flat indices into the accumulation image (row-major ``shape``); ``zyx``
    are index coordinates ``(n, 3)``; ``dt`` is the world distance each sample stands
    for (a float, or ``(n,)`` when it varies per ray).
    """

    rays: np.ndarray
    zyx: np.ndarray
    dt: float | np.ndarray


class SamplePlan:
    """Where samples go, in what order, and how ray results become the image."""

    def __init__(self, kind: str, scene: Scene, volume: Volume) -> None:
        self.kind = kind
        self.scene = scene
        self.volume = volume
        self.camera = Camera.from_view(scene.view, volume)
        self.step_length = scene.render.step * min(volume.spacing)  # world units
        self.n = np.asarray(volume.shape, dtype=np.float64)
        self.lo, self.hi = -0.5, self.n - 0.5
        cam = self.camera
        self.origins = world_to_index(cam.origins, volume)  # (R, 3) zyx
        self.dirs = cam.directions[..., ::-1] / np.asarray(volume.spacing)  # index per world
        self.principal_axis: int | None = None
        if kind == "ray":
            self.shape = (cam.height, cam.width)
            self._setup_ray()
        else:
            central = cam.d[::-1] / np.asarray(volume.spacing)
            self.principal_axis = int(np.argmax(np.abs(central)))
            ss = scene.render.supersampling
            count = int(np.floor((self.n[self.principal_axis] - 1) * ss + 1e-9)) + 1
            self.slices = np.arange(count) / ss  # slice coordinates along the principal axis
            if kind == "shear-image":
                self.shape = (cam.height, cam.width)
                self._setup_shear_image()
            else:
                self._setup_shear_warp()

    # ------------------------------------------------------------------ ray caster

    def _box_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """Entry and exit ray parameters ``t`` of every ray through the box."""
        o = self.origins
        d = np.broadcast_to(self.dirs, o.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (self.lo - o) / d
            t2 = (self.hi - o) / d
        # A ray parallel to an axis's faces is unconstrained on that axis when it lies
        # between them and misses the box when it does not.
        flat = np.abs(d) < _TINY
        inside = (o >= self.lo) & (o <= self.hi)
        near = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        far = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        t_in = near.max(axis=1)
        t_out = far.min(axis=1)
        if self.camera.perspective:
            t_in = np.maximum(t_in, 0.0)
        return t_in, t_out

    def _setup_ray(self) -> None:
        t_in, t_out = self._box_interval()
        dt = self.step_length
        with np.errstate(invalid="ignore"):
            # Half-open [t_in, t_out): a slab of length L holds exactly L / dt samples
            # when its faces fall on the lattice.
            k_lo = np.ceil(t_in / dt - 1e-9)
            k_hi = np.ceil(t_out / dt - 1e-9) - 1
        hit = np.isfinite(k_lo) & np.isfinite(k_hi) & (k_lo <= k_hi)
        self.hit_rays = np.flatnonzero(hit)
        self.k_lo = k_lo[hit].astype(np.int64)
        self.k_hi = k_hi[hit].astype(np.int64)
        self.k_range = (int(self.k_lo.min()), int(self.k_hi.max())) if hit.any() else (0, -1)
        self.n_steps = self.k_range[1] - self.k_range[0] + 1

    def _steps_ray(self) -> Iterator[Step]:
        dt = self.step_length
        o = self.origins[self.hit_rays]
        d = self.dirs if self.dirs.ndim == 1 else self.dirs[self.hit_rays]
        for k in range(self.k_range[0], self.k_range[1] + 1):
            sel = np.flatnonzero((self.k_lo <= k) & (k <= self.k_hi))
            dd = d if d.ndim == 1 else d[sel]
            yield Step(self.hit_rays[sel], o[sel] + (k * dt) * dd, dt)

    # ------------------------------------------------------------------ shear-image

    def _setup_shear_image(self) -> None:
        t_in, t_out = self._box_interval()
        kp = self.principal_axis
        d = np.broadcast_to(self.dirs, self.origins.shape)
        ok = (t_in <= t_out) & (np.abs(d[:, kp]) > _TINY)
        self.hit_rays = np.flatnonzero(ok)
        self.n_steps = self.slices.size

    def _steps_shear_image(self) -> Iterator[Step]:
        kp = self.principal_axis
        rays = self.hit_rays
        o = self.origins[rays]
        d = np.broadcast_to(self.dirs, self.origins.shape)[rays]
        forward = d[:, kp] > 0
        spacing_t = (1.0 / self.scene.render.supersampling) / np.abs(d[:, kp])
        last = self.slices.size - 1
        for j in range(self.slices.size):
            q = np.where(forward, self.slices[j], self.slices[last - j])
            t = (q - o[:, kp]) / d[:, kp]
            pos = o + t[:, None] * d
            keep = np.all((pos >= self.lo) & (pos <= self.hi), axis=1)
            if self.camera.perspective:
                keep &= t >= 0.0
            sel = np.flatnonzero(keep)
            yield Step(rays[sel], pos[sel], spacing_t[sel])

    # ------------------------------------------------------------------ shear-warp

    def _setup_shear_warp(self) -> None:
        if self.camera.perspective:
            raise InputError(
                "shear-warp sampling needs a parallel view",
                key="view.projection",
                allowed="parallel (or sampling ray / shear-image)",
            )
        kp = self.principal_axis
        self.other_axes = tuple(a for a in range(3) if a != kp)
        d = self.dirs
        forward = d[kp] > 0
        self.order = self.slices if forward else self.slices[::-1]
        self.q_ref = float(self.order[0])  # the base plane is the front slice
        self.shear = np.array([d[a] / d[kp] for a in self.other_axes])
        offsets = np.outer(self.order - self.q_ref, self.shear)  # (slices, 2)
        lo = np.ceil(self.lo - offsets.max(axis=0) - 1e-9)
        hi = np.floor(self.hi[list(self.other_axes)] - offsets.min(axis=0) + 1e-9)
        self.base_origin = lo  # base-plane integer coordinates of pixel (0, 0)
        self.shape = (int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1)
        self.offsets = offsets
        self.n_steps = self.order.size
        self.dt_slice = (1.0 / self.scene.render.supersampling) / abs(d[kp])

    def _steps_shear_warp(self) -> Iterator[Step]:
        kp = self.principal_axis
        a_ax, b_ax = self.other_axes
        rows, cols = self.shape
        for q, (da, db) in zip(self.order, self.offsets, strict=True):
            # Base-plane pixels whose ray lies inside the box on this slice: a rectangle.
            a0 = max(0, int(np.ceil(self.lo - da - self.base_origin[0] - 1e-9)))
            a1 = min(rows - 1, int(np.floor(self.hi[a_ax] - da - self.base_origin[0] + 1e-9)))
            b0 = max(0, int(np.ceil(self.lo - db - self.base_origin[1] - 1e-9)))
            b1 = min(cols - 1, int(np.floor(self.hi[b_ax] - db - self.base_origin[1] + 1e-9)))
            if a1 < a0 or b1 < b0:
                yield Step(np.empty(0, np.int64), np.empty((0, 3)), self.dt_slice)
                continue
            ia, ib = np.meshgrid(np.arange(a0, a1 + 1), np.arange(b0, b1 + 1), indexing="ij")
            pos = np.empty((ia.size, 3))
            pos[:, kp] = q
            pos[:, a_ax] = ia.ravel() + self.base_origin[0] + da
            pos[:, b_ax] = ib.ravel() + self.base_origin[1] + db
            yield Step((ia * cols + ib).ravel(), pos, self.dt_slice)

    # ------------------------------------------------------------------ public

    def steps(self) -> Iterator[Step]:
        """Front-to-back steps (deterministic: the same plan yields the same samples)."""
        if self.kind == "ray":
            return self._steps_ray()
        if self.kind == "shear-image":
            return self._steps_shear_image()
        return self._steps_shear_warp()

    @property
    def n_rays(self) -> int:
        return self.shape[0] * self.shape[1]

    def toward_viewer(self, rays: np.ndarray) -> np.ndarray:
        """Unit world vectors toward the viewer for ``rays`` (``(3,)`` when shared)."""
        dirs = self.camera.directions
        if dirs.ndim == 1 or self.kind == "shear-warp":
            return -self.camera.d
        return -dirs[rays]

    def to_image(self, acc: np.ndarray, background: float = 0.0) -> np.ndarray:
        """Accumulated ray values ``(n_rays, ...)`` as the final ``(H, W, ...)`` image.

        Rays that took no sample must hold ``background`` already.  For shear-warp this
        is the 2-D warp: each final pixel's ray meets the base plane at a point that is
        resampled bilinearly (``background`` outside the base plane).
        """
        base = acc.reshape(self.shape + acc.shape[1:])
        if self.kind != "shear-warp":
            return base
        cam = self.camera
        kp = self.principal_axis
        a_ax, b_ax = self.other_axes
        t = (self.q_ref - self.origins[:, kp]) / self.dirs[kp]
        a = self.origins[:, a_ax] + t * self.dirs[a_ax] - self.base_origin[0]
        b = self.origins[:, b_ax] + t * self.dirs[b_ax] - self.base_origin[1]
        return bilinear_2d(base, a, b, background).reshape((cam.height, cam.width) + acc.shape[1:])

    def describe(self) -> dict:
        """Plain-data summary for reports."""
        out = {
            "kind": self.kind,
            "shape": list(self.shape),
            "steps": self.n_steps,
            "step_length": self.step_length,
        }
        if self.principal_axis is not None:
            out["principal_axis"] = "zyx"[self.principal_axis]
        return out


def bilinear_2d(image: np.ndarray, a: np.ndarray, b: np.ndarray, background: float) -> np.ndarray:
    """Sample ``image[a, b, ...]`` bilinearly; points off the image blend to ``background``."""
    rows, cols = image.shape[:2]
    pad = np.full((rows + 2, cols + 2) + image.shape[2:], background, dtype=np.float64)
    pad[1:-1, 1:-1] = image
    a = np.clip(a + 1.0, 0.0, rows + 1.0)
    b = np.clip(b + 1.0, 0.0, cols + 1.0)
    a0 = np.minimum(np.floor(a).astype(np.int64), rows)
    b0 = np.minimum(np.floor(b).astype(np.int64), cols)
    fa, fb = a - a0, b - b0
    if image.ndim == 3:
        fa, fb = fa[:, None], fb[:, None]
    return (1 - fa) * ((1 - fb) * pad[a0, b0] + fb * pad[a0, b0 + 1]) + fa * (
        (1 - fb) * pad[a0 + 1, b0] + fb * pad[a0 + 1, b0 + 1]
    )


def make_plan(scene: Scene, volume: Volume, sampling: str = "ray") -> SamplePlan:
    """The :class:`SamplePlan` of ``sampling`` for ``scene`` on ``volume``."""
    if sampling not in SAMPLINGS:
        raise InputError(
            f"unknown sampling {sampling!r}", key="sampling", allowed=", ".join(SAMPLINGS)
        )
    if sampling == "slice-parallel":
        sampling = "shear-image" if scene.view.projection == "perspective" else "shear-warp"
    return SamplePlan(sampling, scene, volume)
