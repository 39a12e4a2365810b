"""Sample positions: the ideal ray caster's and each architecture's processing order.

# Ref: Lacroute & Levoy, SIGGRAPH 1994 (shear-warp); Wu et al., I3D 2003 (shear-image);
#      Pfister & Kaufman, VolVis 1996 (Cube-4 slice-parallel); architectures.md section 6.

A :class:`SamplePlan` says *where* samples are taken and how the accumulated rays become
the final image; it knows nothing of classification or shading, so the float64 golden
renderer and the fixed-point renderers iterate the same plan and differ only in
arithmetic.  Positions are index coordinates ``(z, y, x)`` (voxel centres at integers,
box ``[-0.5, n - 0.5]``), float64.  Kinds:

``ray``
    Rays through the image's pixel centres, samples every ``dt`` world units on a lattice
    shared by all rays (``t = k dt``; ``t = 0`` on the plane through the volume centre for
    parallel views, at the eye for perspective), kept where ``t_in <= t < t_out`` (entry
    and exit of the box; half-open, so no face is counted twice).
``shear-image`` (VolumePro 1000)
    Rays through the image's pixel centres, sampled where they cross the slice planes of
    the principal axis (voxel slices, plus ``1/supersampling`` sub-slices), kept inside
    the box (inclusive, to 1e-9 index units).
``shear-warp`` (VolumePro 500, EM-Cube; parallel only)
    Rays from the integer pixels of a base plane parallel to the slices (the front
    slice), sampled on every slice at a shear offset that is the same for the whole
    slice; the base-plane image is warped to the final image by bilinear resampling.
``slice-parallel`` (Cube-4)
    ``shear-warp`` for parallel views, ``shear-image`` for perspective.

The principal axis is the index axis with the largest ``|d / spacing|`` component (ties
go to z, then y, then x).  Every kind is one engine: ray ``r`` takes a sample at each
global step ``j`` in ``[j_lo[r], j_hi[r]]``, at a position linear in ``j``.  Given an
:class:`~hwsim.golden.occupancy.Occupancy`, the plan shortens those ranges from both
ends past blocks that cannot be visible (:meth:`SamplePlan.leap`).
"""

from __future__ import annotations

import copy
from collections.abc import Iterator

import numba
import numpy as np

from hwsim.core.errors import InputError
from hwsim.golden.camera import Camera, world_to_index
from hwsim.golden.leap_rays import leap_ray_plan
from hwsim.golden.occupancy import Occupancy
from hwsim.golden.steps import Step, bilinear_2d, linear_range, run_steps
from hwsim.spec.scene import Scene
from hwsim.volumes.volume import Volume

__all__ = ["SAMPLINGS", "Step", "SamplePlan", "make_plan"]

SAMPLINGS = ("ray", "shear-warp", "shear-image", "slice-parallel")
_TINY = 1e-12


class SamplePlan:
    """Where samples go, in what order, and how ray results become the image.

    Attributes: ``shape`` (rows, cols of the accumulation image), ``ray_ids`` (flat
    indices of rays that take a sample), ``j_lo``/``j_hi`` (their inclusive step
    ranges), ``n_steps``, ``principal_axis`` (slice kinds; None for ``ray``).
    """

    def __init__(
        self, kind: str, scene: Scene, volume: Volume, occupancy: Occupancy | None = None
    ) -> None:
        self.kind, self.scene, self.volume = kind, scene, volume
        self.camera = cam = Camera.from_view(scene.view, volume)
        self.step_length = scene.render.step * min(volume.spacing)  # world units
        self.n = np.asarray(volume.shape, dtype=np.float64)
        self.lo, self.hi = -0.5, self.n - 0.5
        self.origins = world_to_index(cam.origins, volume)  # (R, 3) zyx
        self.dirs = cam.directions[..., ::-1] / np.asarray(volume.spacing)  # index per world
        self.principal_axis: int | None = None
        self.leap_block: int | None = None
        render = scene.render
        #: Samples walked from each ray's far end (VLI's back-to-front blending).
        self.back_to_front = render.mode == "composite" and render.blend_order == "back-to-front"
        self._per_ray = ["ray_ids", "j_lo", "j_hi"]
        if kind == "ray":
            self.shape = (cam.height, cam.width)
            self._setup_ray()
        else:
            central = cam.d[::-1] / np.asarray(volume.spacing)
            self.principal_axis = int(np.argmax(np.abs(central)))
            ss = scene.render.supersampling
            self.slice_count = int(np.floor((self.n[self.principal_axis] - 1) * ss + 1e-9)) + 1
            if kind == "shear-image":
                self.shape = (cam.height, cam.width)
                self._setup_shear_image()
            else:
                self._setup_shear_warp()
        if self.back_to_front:
            self._reverse()
        if cam.perspective and kind != "shear-warp":
            self._view = -cam.directions[self.ray_ids]
            self._per_ray.append("_view")
        else:
            self._view = -cam.d
        self._keep(self.j_lo <= self.j_hi)
        if occupancy is not None:
            self.leap(occupancy)

    # ------------------------------------------------------------------ kinds

    def _box_interval(self) -> tuple[np.ndarray, np.ndarray]:
        """Entry and exit ray parameters ``t`` of every image ray through the box."""
        o = self.origins
        d = np.broadcast_to(self.dirs, o.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (self.lo - o) / d, (self.hi - o) / d
        # A ray parallel to an axis's faces is unconstrained on that axis when it lies
        # between them and misses the box when it does not.
        flat = np.abs(d) < _TINY
        inside = (o >= self.lo) & (o <= self.hi)
        near = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        far = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        t_in, t_out = near.max(axis=1), far.min(axis=1)
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
        hit = np.flatnonzero(np.isfinite(k_lo) & np.isfinite(k_hi) & (k_lo <= k_hi))
        self.k_min = int(k_lo[hit].min()) if hit.size else 0
        #: Step ``j`` is at ``t = (k_first + k_dir j) dt``.
        self.k_first, self.k_dir = self.k_min, 1
        self.ray_ids = hit
        self.j_lo = k_lo[hit].astype(np.int64) - self.k_min
        self.j_hi = k_hi[hit].astype(np.int64) - self.k_min
        self.n_steps = int(self.j_hi.max()) + 1 if hit.size else 0
        self._o = self.origins[hit]
        self._d = self.dirs if self.dirs.ndim == 1 else self.dirs[hit]
        self._dt = dt
        self._delta = dt * self._d
        self._per_ray += ["_o"] + (["_d", "_delta"] if self._d.ndim == 2 else [])

    def _setup_shear_image(self) -> None:
        kp, ss = self.principal_axis, self.scene.render.supersampling
        d = np.broadcast_to(self.dirs, self.origins.shape)
        rays = np.flatnonzero(np.abs(d[:, kp]) > _TINY)
        self._o, self._d = self.origins[rays], d[rays]
        self._sign = np.where(self._d[:, kp] > 0, 1.0, -1.0)  # slices front to back
        self._q0 = np.where(self._sign > 0, 0.0, (self.slice_count - 1) / ss)
        tstep = self._sign / ss / self._d[:, kp]  # > 0: ray parameter per step
        self._dt, self._delta = tstep, tstep[:, None] * self._d
        self._delta[:, kp] = self._sign / ss
        self.ray_ids = rays
        self.n_steps = self.slice_count
        self._per_ray += ["_o", "_d", "_sign", "_q0", "_dt", "_delta"]
        j_lo, j_hi = linear_range(self._position_all(0), self._delta, self.lo, self.hi)
        if self.camera.perspective:  # t = t0 + j tstep >= 0
            t0 = (self._q0 - self._o[:, kp]) / self._d[:, kp]
            j_lo = np.maximum(j_lo, np.ceil(-t0 / tstep - 1e-9))
        self._set_ranges(j_lo, j_hi)

    def _setup_shear_warp(self) -> None:
        if self.camera.perspective:
            raise InputError(
                "shear-warp sampling needs a parallel view",
                key="view.projection",
                allowed="parallel (or sampling ray / shear-image)",
            )
        kp, ss = self.principal_axis, self.scene.render.supersampling
        self.other_axes = tuple(a for a in range(3) if a != kp)
        d = self.dirs
        slices = np.arange(self.slice_count) / ss
        self.order = slices if d[kp] > 0 else slices[::-1]
        self.q_ref = float(self.order[0])  # the base plane is the front slice
        self.shear = np.array([d[a] / d[kp] for a in self.other_axes])
        self.offsets = np.outer(self.order - self.q_ref, self.shear)  # (slices, 2)
        lo = np.ceil(self.lo - self.offsets.max(axis=0) - 1e-9)
        hi = np.floor(self.hi[list(self.other_axes)] - self.offsets.min(axis=0) + 1e-9)
        self.base_origin = lo  # base-plane integer coordinates of pixel (0, 0)
        self.shape = (int(hi[0] - lo[0]) + 1, int(hi[1] - lo[1]) + 1)
        self.n_steps = self.slice_count
        self._dt = (1.0 / ss) / abs(d[kp])
        self._delta = np.zeros(3)
        self._delta[kp] = np.sign(d[kp]) / ss
        self._delta[list(self.other_axes)] = self.shear * self._delta[kp]
        self.ray_ids = np.arange(self.shape[0] * self.shape[1])
        # Step 0 of every ray: position()'s terms with one offset row for all.
        start = self.position(0, slice(None))
        self._set_ranges(*linear_range(start, self._delta, self.lo, self.hi))

    def _reverse(self) -> None:
        """Walk every ray from its far end: step ``j`` becomes the front-to-back plan's
        step ``n_steps - 1 - j``, at the same position (shear-warp keeps its base plane,
        the front slice)."""
        last = self.n_steps - 1
        self.j_lo, self.j_hi = last - self.j_hi, last - self.j_lo
        self._delta = -self._delta
        if self.kind == "ray":
            self.k_first, self.k_dir = self.k_min + last, -1
        elif self.kind == "shear-image":
            self._sign = -self._sign
            self._q0 = np.where(self._sign > 0, 0.0, last / self.scene.render.supersampling)
        else:
            self.order = self.order[::-1].copy()
            self.offsets = self.offsets[::-1].copy()

    def _set_ranges(self, j_lo: np.ndarray, j_hi: np.ndarray) -> None:
        j_lo, j_hi = np.maximum(j_lo, 0.0), np.minimum(j_hi, self.n_steps - 1.0)
        ok = j_lo <= j_hi
        self.j_lo = np.where(ok, j_lo, 0).astype(np.int64)
        self.j_hi = np.where(ok, j_hi, -1).astype(np.int64)

    def position(self, j: int | np.ndarray, sel: np.ndarray) -> np.ndarray:
        """Index positions ``(len(sel), 3)`` of plan rays ``sel`` at step(s) ``j``."""
        if self.kind == "ray":
            t = (self.k_first + self.k_dir * j) * self._dt
            d = self._d if self._d.ndim == 1 else self._d[sel]
            return self._o[sel] + (t * d if np.isscalar(t) else t[:, None] * d)
        kp = self.principal_axis
        if self.kind == "shear-image":
            if np.ndim(j) == 0:  # one step: compiled, the same bits (_shear_image_rows)
                sel = np.asarray(sel)
                if sel.dtype == bool:
                    sel = np.flatnonzero(sel)
                pos = np.empty((sel.size, 3))
                _shear_image_rows(
                    self._shear_image_rays(), float(j),
                    float(self.scene.render.supersampling), kp, sel.ravel(), pos,
                )  # fmt: skip
                return pos
            return self._shear_image_numpy(j, sel)
        a_ax, b_ax = self.other_axes
        ids = self.ray_ids[sel]
        off = self.offsets[j]
        pos = np.empty((ids.size, 3))
        pos[:, kp] = self.order[j]
        pos[:, a_ax] = ids // self.shape[1] + self.base_origin[0] + off[..., 0]
        pos[:, b_ax] = ids % self.shape[1] + self.base_origin[1] + off[..., 1]
        return pos

    def _shear_image_rays(self) -> np.ndarray:
        """``(rays, 8)``: each plan ray's ``q0``, ``sign``, origin and direction in one row
        (one cache line a ray for :func:`_shear_image_rows`); rebuilt when any of those
        arrays is replaced (:meth:`_keep`, :meth:`_reverse`, :meth:`subset`)."""
        arrays = (self._q0, self._sign, self._o, self._d)
        packed = self.__dict__.get("_packed")
        if packed is None or any(a is not b for a, b in zip(packed[0], arrays, strict=True)):
            rays = np.empty((self._o.shape[0], 8))
            rays[:, 0], rays[:, 1], rays[:, 2:5], rays[:, 5:8] = arrays
            self._packed = packed = (arrays, rays)
        return packed[1]

    def _shear_image_numpy(self, j: int | np.ndarray, sel: np.ndarray) -> np.ndarray:
        """The ``shear-image`` positions in NumPy (any ``j``): the reference
        :func:`_shear_image_rows` is compared with (``tests/golden/test_plans.py``)."""
        kp = self.principal_axis
        q = self._q0[sel] + self._sign[sel] * (np.asarray(j) / self.scene.render.supersampling)
        o, d = self._o[sel], self._d[sel]
        pos = o + ((q - o[:, kp]) / d[:, kp])[:, None] * d
        pos[:, kp] = q  # exactly on the slice
        return pos

    def principal_position(self, j: int, forward: bool) -> float:
        """Principal-axis position of slice step ``j`` of a slice plan whose slices are
        processed in increasing index order when ``forward``."""
        if self.kind == "shear-warp":
            return float(self.order[j])
        ss = self.scene.render.supersampling
        q0 = 0.0 if forward else (self.slice_count - 1) / ss
        return q0 + (1.0 if forward else -1.0) * (j / ss)

    def _position_all(self, j: int) -> np.ndarray:
        return self.position(np.full(self.ray_ids.size, j), np.arange(self.ray_ids.size))

    # ------------------------------------------------------------------ public

    def _keep(self, keep: np.ndarray) -> None:
        """Keep only the plan rays where ``keep`` is True (per-ray arrays filtered)."""
        for name in self._per_ray:
            setattr(self, name, getattr(self, name)[keep])

    def subset(self, keep: np.ndarray) -> SamplePlan:
        """The same plan holding only the rays where ``keep`` (bool per plan ray) is True:
        each kept ray's samples at the same positions (every position is a function of
        its own ray), for a frame split by rays."""
        part = copy.copy(self)
        part._keep(np.asarray(keep, dtype=bool))
        return part

    def reordered(self, order: np.ndarray) -> SamplePlan:
        """The same plan with its rays in ``order`` (a permutation of the plan rays'
        indices): ray ``i`` of it is ray ``order[i]`` of this one, with the same
        positions (every position is a function of its own ray)."""
        part = copy.copy(self)
        part._keep(np.asarray(order, dtype=np.int64))
        return part

    def leap(self, occupancy: Occupancy) -> None:
        """Shorten every ray's step range past blocks that ``occupancy`` marks empty.

        Exact: a skipped sample lies in a block at chessboard distance >= 1 from every
        occupied block.  Leaps are ``floor((c - 1) block / |delta|_inf)`` steps (at least
        one) from a block at distance ``c``, or to the first sample outside the current
        block when that is farther; ``delta`` is the per-step displacement.
        """
        self.leap_block = occupancy.block
        if occupancy.empty:
            self._keep(np.zeros(self.ray_ids.size, dtype=bool))
            return
        if self.kind == "ray":  # compiled, the same ranges (hwsim.golden.leap_rays)
            self.j_lo, self.j_hi = leap_ray_plan(self, occupancy)
        else:
            self.j_lo, self.j_hi = self._march(occupancy)
        # Drop rays left without samples only after both passes: the per-ray step
        # vectors were read for every ray.  :meth:`_keep`'s rows, by ``np.compress``
        # (several times faster than a boolean index of an ``(n, 3)`` array).
        keep = self.j_lo <= self.j_hi
        for name in self._per_ray:
            setattr(self, name, np.compress(keep, getattr(self, name), axis=0))

    def _march(self, occupancy: Occupancy) -> tuple[np.ndarray, np.ndarray]:
        """The leap's march in NumPy over the rays still marching: new ``(j_lo, j_hi)``."""
        j_lo0, j_hi0 = self.j_lo, self.j_hi
        delta = np.broadcast_to(self._delta, (self.ray_ids.size, 3))
        reach = np.maximum(
            np.maximum(np.abs(delta[:, 0]), np.abs(delta[:, 1])), np.abs(delta[:, 2])
        )
        b = occupancy.block
        for sign in (1, -1):
            j = (self.j_lo if sign > 0 else self.j_hi).copy()
            # Rays the forward march found empty take no backward march.
            march = np.flatnonzero(self.j_lo <= self.j_hi)
            while march.size:
                p = self.position(j[march], march)
                block = np.clip(p, 0.0, self.n - 1.0) // b
                c = occupancy.distance_of(block)
                skip = np.floor(((c - 1) * b - 1e-6) / reach[march])
                # Or to the first sample that leaves the current (empty) block.
                step = sign * delta[march]
                face = np.where(step > 0, (block + 1) * b - p, p - block * b)
                moving = np.abs(step) > _TINY
                along = np.divide(face, np.abs(step), out=np.full(face.shape, np.inf), where=moving)
                along = np.minimum(np.minimum(along[:, 0], along[:, 1]), along[:, 2])
                skip = np.maximum(np.maximum(skip, np.ceil(along - 1e-6)), 1)
                j[march] += sign * np.where(c > 0, skip, 0).astype(np.int64)
                inside = (j[march] <= self.j_hi[march]) & (j[march] >= self.j_lo[march])
                march = march[(c > 0) & inside]
            if sign > 0:
                # An empty ray's canonical form: ``j_lo = j_hi + 1``, ``j_hi`` unchanged.
                self.j_lo = np.minimum(j, self.j_hi + 1)
            else:
                self.j_hi = j
        out = self.j_lo, self.j_hi
        self.j_lo, self.j_hi = j_lo0, j_hi0
        return out

    def steps(self, alive: np.ndarray | None = None) -> Iterator[Step]:
        """The steps in blending order (front to back, or back to front where
        :attr:`back_to_front`), one per ``j`` in ``range(n_steps)`` (possibly empty).

        ``alive`` (optional, bool per accumulation ray) is read at every step: rays set
        False stop being yielded (early termination).  Deterministic.
        """
        return run_steps(self, alive)

    @property
    def n_rays(self) -> int:
        return self.shape[0] * self.shape[1]

    @property
    def samples(self) -> int:
        """Samples the plan holds (before any early termination)."""
        return int(np.sum(self.j_hi - self.j_lo + 1))

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
        a, b = np.empty(self.origins.shape[0]), np.empty(self.origins.shape[0])
        _base_points(
            self.origins, self.dirs, self.q_ref, self.principal_axis, *self.other_axes,
            float(self.base_origin[0]), float(self.base_origin[1]), a, b,
        )  # fmt: skip
        image = bilinear_2d(base, a, b, background)
        return image.reshape((self.camera.height, self.camera.width) + acc.shape[1:])

    def describe(self) -> dict:
        """Plain-data summary for reports."""
        out = {
            "kind": self.kind,
            "shape": list(self.shape),
            "steps": self.n_steps,
            "step_length": self.step_length,
            "rays": int(self.ray_ids.size),
            "samples": self.samples,
            "leap_block": self.leap_block,
        }
        if self.back_to_front:
            out["blend_order"] = "back-to-front"
        if self.principal_axis is not None:
            out["principal_axis"] = "zyx"[self.principal_axis]
        return out


@numba.njit(cache=True, nogil=True)
def _shear_image_rows(rays, j, ss, kp, sel, out):  # pragma: no cover - compiled
    """:meth:`SamplePlan._shear_image_numpy` at one step ``j``, one ray at a time (``rays``:
    :meth:`SamplePlan._shear_image_rays`): the same float64 operations in the same order
    (``q = q0 + sign (j / ss)``, ``o + ((q - o_kp) / d_kp) d``, no fused multiply-adds),
    so the same bits, without the gathered copies."""
    step = j / ss
    for i in range(sel.size):
        r = sel[i]
        q = rays[r, 0] + rays[r, 1] * step
        t = (q - rays[r, 2 + kp]) / rays[r, 5 + kp]
        for ax in range(3):
            out[i, ax] = rays[r, 2 + ax] + t * rays[r, 5 + ax]
        out[i, kp] = q  # exactly on the slice


@numba.njit(cache=True, nogil=True)
def _base_points(origins, dirs, q_ref, kp, a_ax, b_ax, a0, b0, a, b):  # pragma: no cover
    """Where each final pixel's ray meets the base plane, in base-plane pixels:
    ``t = (q_ref - o_kp) / d_kp``, ``a = o_a + t d_a - a0``, ``b = o_b + t d_b - b0``,
    one ray at a time (the array expression's operations, no fused multiply-adds)."""
    for i in range(origins.shape[0]):
        t = (q_ref - origins[i, kp]) / dirs[kp]
        a[i] = origins[i, a_ax] + t * dirs[a_ax] - a0
        b[i] = origins[i, b_ax] + t * dirs[b_ax] - b0


def make_plan(
    scene: Scene, volume: Volume, sampling: str = "ray", *, occupancy: Occupancy | None = None
) -> SamplePlan:
    """The :class:`SamplePlan` of ``sampling`` for ``scene`` on ``volume``.

    ``occupancy`` (optional) shortens rays past empty blocks; without it every sample in
    the box is planned (what a machine without space leaping visits).
    """
    if sampling not in SAMPLINGS:
        raise InputError(
            f"unknown sampling {sampling!r}", key="sampling", allowed=", ".join(SAMPLINGS)
        )
    if sampling == "slice-parallel":
        sampling = "shear-image" if scene.view.projection == "perspective" else "shear-warp"
    return SamplePlan(sampling, scene, volume, occupancy)
