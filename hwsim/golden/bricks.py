"""Supervolume bricks: a volume larger than a machine renders in one pass, split into
machine-sized bricks, each owning the samples of the whole volume's plan inside it.

# Ref: architectures.md section 3 (VolumePro 500: "up to 256 voxels in every dimension;
#      larger 'supervolumes' split in software", [V] FAQ and SIGGRAPH 99 abstract); how
#      the software split them (overlap, ownership, blend) is not published: [I] here.

Every axis longer than the machine's limit ``m`` is cut into ``k = ceil(n / (m - 2h))``
cores of near-equal length; a brick holds its core plus ``h`` voxels of halo on each side
inside the volume, so it never exceeds ``m``.  ``h = 2`` covers what a sample needs
around it: trilinear taps one voxel away, and central differences one voxel further
(of samples or of voxels).  A brick *owns* the sample positions ``p`` with
``core_lo <= p < core_hi`` on every axis (index coordinates; the outermost bounds are
infinite), so every sample of the whole plan belongs to exactly one brick: ownership is
decided on the whole plan's own position of each sample.

A :class:`BrickPlan` is the whole plan restricted to one brick's samples, in the brick's
coordinates (the whole plan's positions minus the brick origin: exact in float64, the
origin being an integer), with its steps renumbered from the first step that has a
sample in the brick, so a machine visits only the brick's slices.  Its rays keep the
whole plan's base-plane (or image) pixel ids, and it does not warp: the host blends the
bricks' base-plane images, then warps once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.golden.positions import SamplePlan
from hwsim.golden.steps import linear_range
from hwsim.volumes.volume import Volume

__all__ = ["HALO", "Brick", "BrickPlan", "split_bricks"]

#: Voxels of overlap each side of an inner brick face [I].
HALO = 2


@dataclass(frozen=True)
class Brick:
    """One brick: voxels ``lo .. hi - 1`` (z, y, x) and the positions it owns,
    ``core_lo <= p < core_hi`` (index coordinates of the whole volume)."""

    index: tuple[int, int, int]
    lo: tuple[int, int, int]
    hi: tuple[int, int, int]
    core_lo: tuple[float, float, float]
    core_hi: tuple[float, float, float]

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(h - lo for lo, h in zip(self.lo, self.hi, strict=True))  # type: ignore[return-value]

    @property
    def label(self) -> str:
        return "brick " + ",".join(map(str, self.index))


def _cuts(n: int, m: int, halo: int) -> list[int]:
    """Core boundaries along an axis of ``n`` voxels for bricks of at most ``m``."""
    if n <= m:
        return [0, n]
    if m <= 2 * halo:
        raise ValueError(f"a brick of {m} voxels cannot hold a halo of {halo} each side")
    k = -(-n // (m - 2 * halo))
    return [round(i * n / k) for i in range(k + 1)]


def split_bricks(
    shape: tuple[int, int, int], max_shape: tuple[int, int, int], halo: int = HALO
) -> list[Brick]:
    """The bricks of a ``shape`` volume for a machine of ``max_shape`` (z, y, x), in
    z, y, x index order (one brick when the volume fits)."""
    cuts = [_cuts(n, m, halo) for n, m in zip(shape, max_shape, strict=True)]
    bricks = []
    for iz in range(len(cuts[0]) - 1):
        for iy in range(len(cuts[1]) - 1):
            for ix in range(len(cuts[2]) - 1):
                idx = (iz, iy, ix)
                lo, hi, core_lo, core_hi = [], [], [], []
                for axis, i in enumerate(idx):
                    c, n = cuts[axis], shape[axis]
                    lo.append(max(0, c[i] - halo))
                    hi.append(min(n, c[i + 1] + halo))
                    core_lo.append(-np.inf if i == 0 else c[i] - 0.5)
                    core_hi.append(np.inf if i + 1 == len(c) - 1 else c[i + 1] - 0.5)
                bricks.append(Brick(idx, tuple(lo), tuple(hi), tuple(core_lo), tuple(core_hi)))  # type: ignore[arg-type]
    return bricks


def _owned(p: np.ndarray, brick: Brick) -> np.ndarray:
    return np.all((p >= np.asarray(brick.core_lo)) & (p < np.asarray(brick.core_hi)), axis=1)


def owned_ranges(plan: SamplePlan, brick: Brick) -> tuple[np.ndarray, np.ndarray]:
    """Per plan ray, the first and last step whose sample ``brick`` owns (``lo > hi``:
    none).  Positions are linear (and monotone) in the step, so the owned steps of a ray
    are one run: found from the linear bounds widened by 1e-6, then trimmed on the
    plan's own positions."""
    rays = np.arange(plan.ray_ids.size)
    start = plan.position(plan.j_lo, rays)
    delta = np.broadcast_to(plan._delta, start.shape)
    margin = 1e-6
    first, last = linear_range(
        start, delta, np.asarray(brick.core_lo) - margin, np.asarray(brick.core_hi) + margin
    )
    with np.errstate(invalid="ignore"):
        lo = np.clip(np.nan_to_num(first, nan=np.inf, posinf=1e18, neginf=-1e18), 0, 1e18)
        hi = np.nan_to_num(last, nan=-np.inf, posinf=1e18, neginf=-1e18)
    lo = plan.j_lo + lo.astype(np.int64)
    hi = np.minimum(plan.j_lo + np.maximum(hi, -1).astype(np.int64), plan.j_hi)
    for end, step in ((lo, 1), (hi, -1)):
        while True:
            live = np.flatnonzero(lo <= hi)
            if not live.size:
                break
            bad = live[~_owned(plan.position(end[live], live), brick)]
            if not bad.size:
                break
            end[bad] += step
    return lo, hi


class BrickPlan(SamplePlan):
    """The samples of ``plan`` that ``brick`` owns, in the coordinates of ``volume`` (the
    brick's voxels).  See the module docstring."""

    def __init__(self, plan: SamplePlan, brick: Brick, volume: Volume) -> None:
        if plan.kind == "ray":
            raise ValueError("supervolume bricks are modelled for slice-order plans")
        self.__dict__.update(plan.__dict__)
        self.whole, self.brick, self.volume = plan, brick, volume
        self.origin = origin = np.asarray(brick.lo, dtype=np.float64)
        lo, hi = owned_ranges(plan, brick)
        keep = lo <= hi
        self._whole_rays = np.flatnonzero(keep)
        self.j0 = j0 = int(lo[keep].min()) if keep.any() else 0
        j1 = int(hi[keep].max()) if keep.any() else -1
        self.n_steps = j1 - j0 + 1
        for name in plan._per_ray:
            setattr(self, name, getattr(plan, name)[keep])
        #: The whole plan's first step of each ray in this brick (the host's blend order).
        self.first_step = lo[keep]
        self.j_lo, self.j_hi = lo[keep] - j0, hi[keep] - j0
        self._per_ray = [*plan._per_ray, "_whole_rays", "first_step"]
        self.n = np.asarray(volume.shape, dtype=np.float64)
        self.lo, self.hi = -0.5, self.n - 0.5
        kp = plan.principal_axis
        # The plan's terms moved into the brick (read by the models' own position walks
        # and slice bookkeeping; :meth:`position` is the exact reference).
        if plan.kind == "shear-warp":
            others = list(plan.other_axes)
            self.order = plan.order[j0 : j1 + 1] - origin[kp]
            self.offsets = plan.offsets[j0 : j1 + 1]
            self.base_origin = plan.base_origin - origin[others]
            self.q_ref = plan.q_ref - origin[kp]
        else:
            ss = plan.scene.render.supersampling
            self._o = self._o - origin
            self._q0 = self._q0 + self._sign * (j0 / ss) - origin[kp]

    def position(self, j, sel):
        """The whole plan's positions of these samples, minus the brick origin."""
        return self.whole.position(j + self.j0, self._whole_rays[sel]) - self.origin

    def principal_position(self, j: int, forward: bool) -> float:
        kp = self.principal_axis
        return self.whole.principal_position(j + self.j0, forward) - float(self.origin[kp])  # type: ignore[index]

    def to_image(self, acc: np.ndarray, background: float = 0.0) -> np.ndarray:
        """The brick's base-plane (or image) accumulators, unwarped: the host blends them."""
        return acc.reshape(self.shape + acc.shape[1:])

    def describe(self) -> dict:
        out = super().describe()
        out["brick"] = {"index": list(self.brick.index), "lo": list(self.brick.lo)}
        return out
