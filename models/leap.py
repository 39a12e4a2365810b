"""Exact work skipping for the bit-exact rungs: leap blocks that are provably invisible.

# Ref: Levoy, "Efficient Ray Tracing of Volume Data", ACM TOG 1990 (empty-space
#      skipping); Lacroute & Levoy, SIGGRAPH 1994 (skipping transparent runs);
#      hwsim/golden/occupancy.py (the same leap, decided in float64).

The modelled machines visit every planned sample (the cycle estimate counts them all);
only the *simulation* skips the ones that cannot change the image.  The golden
renderer's :class:`~hwsim.golden.occupancy.Occupancy` decides visibility with the float
transfer function; here it is decided with the datapath's own arithmetic, so the skip is
exact bit for bit:

* a fixed-point trilinear sample is a convex combination of its cell's corners (every
  lerp ``a + round((b - a) f / 2**W)`` with ``0 <= f <= 2**W`` stays in ``[a, b]``), so
  it lies in the raw range of the block holding the sample and its ``+1`` neighbours
  (:func:`~hwsim.golden.occupancy.block_ranges` of the raw voxels);
* composite, post-classified: the LUT index is non-decreasing in the sample, so a block
  is transparent when no entry between the indices of its range's ends has non-zero
  opacity (:meth:`models.backend.Backend.transparent_ranges`).  Gradient modulation, cut
  planes and opacity correction only scale an opacity of 0 to 0;
* composite, pre-classified: every corner's opacity comes from the same LUT at the
  voxel's own index, so the same test at 0 fraction bits leaves all corners, hence the
  interpolated opacity, at 0;
* iso: a block whose largest raw value (promoted) is below the threshold has no hit.

MIP, MinIP and X-ray use every sample (X-ray also sums every sample's ``dt``): no skip.
Skipped samples are still *visited*: :func:`visits` recounts what the machine takes
(samples, touched rays), including samples past an early termination that the
simulation no longer generates.
"""

from __future__ import annotations

import copy
import weakref

import numpy as np

from hwsim.golden import occupancy as occ
from hwsim.golden.positions import SamplePlan
from hwsim.volumes.volume import Volume
from models.backend import Backend, RayState, subset_step
from models.units import classify as classify_unit
from models.units.voxel import convert_values

__all__ = ["invisible_blocks", "leapt_plan", "step_sample_counts", "visits"]

#: Per-volume block value ranges (as the golden renderer keeps its own): successive
#: frames of one volume do not rescan it.
_BLOCKS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _raw_block_ranges(volume: Volume, bits: int) -> tuple[np.ndarray, np.ndarray]:
    """Raw (``bits``-bit) minimum and maximum of every block and its ``+1`` neighbours.

    The voxel conversion is non-decreasing, so the raw range is the converted value range.
    """
    cache = _BLOCKS.setdefault(volume, {})
    if "values" not in cache:
        cache["values"] = occ.block_ranges(volume.data)
    if bits not in cache:
        lo, hi = cache["values"]
        cache[bits] = (convert_values(lo, volume, bits)[0], convert_values(hi, volume, bits)[0])
    return cache[bits]


def invisible_blocks(backend: Backend) -> occ.Occupancy | None:
    """The :class:`~hwsim.golden.occupancy.Occupancy` of blocks that can hold a sample
    that changes the image, decided in the datapath's arithmetic; None when nothing may
    be skipped (MIP, MinIP, X-ray, embedded geometry, or a back end that exercises unused
    units)."""
    be = backend
    if be.mode not in ("composite", "iso") or be.exercise_unused:
        return None
    if be.scene.cursor is not None:
        return None  # the cursor is drawn over transparent samples too
    if be.scene.geometry is not None:
        # The depth test ends and drops samples in Backend.process, which the recount
        # of visited samples (:func:`visits`) does not replay: simulate every sample.
        return None
    lo, hi = _raw_block_ranges(be.volume, be.dp.voxel_bits)
    if be.mode == "iso":
        return occ.occupancy_from_ranges((hi << be.S) >= be.iso_raw)
    frac = 0 if be.pre_classified else be.S
    first, last = (
        classify_unit.lut_index(r << frac, be.dp.voxel_bits, frac, be.dp.classify) for r in (lo, hi)
    )
    return occ.occupancy_from_ranges(be.transparent_ranges()[first] <= last)


def leapt_plan(plan: SamplePlan, occupancy: occ.Occupancy) -> SamplePlan:
    """A copy of ``plan`` whose rays skip the blocks ``occupancy`` marks empty (the
    positions of the samples kept are the same floats: each is computed per ray)."""
    leapt = copy.copy(plan)
    leapt.leap(occupancy)
    return leapt


def step_sample_counts(plan: SamplePlan) -> np.ndarray:
    """Samples the plan holds at each step ``j`` (int64 ``(n_steps,)``), without
    iterating it: rays with ``j_lo <= j <= j_hi``."""
    n = plan.n_steps
    starts = np.bincount(plan.j_lo, minlength=n + 1)[: n + 1]
    ends = np.bincount(plan.j_hi + 1, minlength=n + 1)[: n + 1]
    return np.cumsum(starts - ends)[:n]


def visits(plan: SamplePlan, backend: Backend, stopped: np.ndarray, state: RayState) -> None:
    """Set ``state.samples`` and ``state.touched`` to what the machine visits in ``plan``.

    ``stopped[r]`` is the step at which ray ``r`` terminated (its last sample; a large
    value for rays that never did).  A ray takes every planned step up to that one that
    the crop box and cut planes keep, as :meth:`Backend.process` counts them.
    """
    be = backend
    if be.scene.crop is None and not be.scene.cut_planes:
        last = np.minimum(plan.j_hi, stopped[plan.ray_ids])
        state.samples = int(np.sum(last - plan.j_lo + 1))
        state.touched[:] = False
        state.touched[plan.ray_ids] = True
        return
    samples = 0
    touched = np.zeros_like(state.touched)
    for j, step in enumerate(plan.steps()):
        step, _ = be.masks(subset_step(step, stopped[step.rays] >= j))
        samples += step.rays.size
        touched[step.rays] = True
    state.samples, state.touched[:] = samples, touched
