"""The functional rung's compiled step walker for shear-warp frames.

# Ref: Lacroute & Levoy, SIGGRAPH 1994 (shear-warp: one sample per base-plane pixel per
#      slice); hwsim/golden/steps.py (the step engine this replaces for such frames);
#      docs/fidelity.md ("How the functional rung simulates fast, exactly").

:func:`models.functional._Functional.run` walks a frame's steps with
:func:`hwsim.golden.steps.run_steps` over a plan shortened by
:meth:`~hwsim.golden.positions.SamplePlan.leap`: NumPy calls per step for the active
set, the positions and the chunks, and a leap march per frame.  On a 256^3 frame that
bookkeeping costs as much as half the compiled composite stage.  Here one compiled call
per step does it for a shear-warp plan:

* the *active set* is kept as in ``run_steps``: rays join at their ``j_lo``, leave after
  their ``j_hi`` or when early termination cleared their ``alive`` flag;
* each active ray's position is the float expression of
  :meth:`SamplePlan.position <hwsim.golden.positions.SamplePlan.position>` for a
  shear-warp plan, term for term and in the same order, so the samples are the same
  floats (``tests/models/test_functional_fused.py`` compares the frames);
* a sample whose block (:data:`~hwsim.golden.occupancy.BLOCK` voxels, position clamped to
  the volume) is not occupied in :func:`models.leap.invisible_blocks` is skipped: its
  trilinear value lies in that block's range, which classifies to opacity 0, so the
  composite stage would drop it unchanged.  This is the same exact argument as the
  plan's leap, applied per sample, so it also skips empty runs inside a ray.

The samples kept in a step go to :class:`models.fused.CompositeKernel` as one part; each
ray is at most once in a step, so the kernel's order-free blend holds.  What the machine
visits (``samples``, touched rays) is recounted from the full plan by
:func:`models.leap.visits`, as on the leapt path.

**Scope.**  Frames the composite kernel runs (:func:`models.fused.eligible`) on a
shear-warp plan whose step length has a correction table, without crop box or cut
planes (their masks stay in :meth:`models.backend.Backend.masks`): :func:`applies`.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from hwsim.golden.occupancy import Occupancy
from hwsim.golden.positions import SamplePlan
from hwsim.golden.steps import Step
from models.backend import Backend, RayState

__all__ = ["applies", "run_steps_compiled"]


def applies(backend: Backend, plan: SamplePlan, kernel, blocks: Occupancy | None) -> bool:
    """Whether :func:`run_steps_compiled` can walk ``plan`` for ``backend``."""
    scene = backend.scene
    return (
        kernel is not None
        and blocks is not None
        and plan.kind == "shear-warp"
        and scene.crop is None
        and not scene.cut_planes
        and kernel.table(plan._dt) is not None
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _step(
    j, order, offsets, base_a, base_b, axes, j_lo, j_hi, ray_ids, join, cursor,
    slots, alive, distance, block_shift, leap_per_block, vol_hi, zyx, rays,
):  # fmt: skip
    """Step ``j``'s kept samples into ``zyx`` and ``rays``; returns how many.

    ``join`` lists plan rays by ascending ``j_lo`` (rays with samples only); ``cursor``
    holds the active count and the next ray to join.  ``slots`` holds the active rays,
    one column each (read in order, compacted in place): ray id, last step, first step
    not leapt, and the bit patterns of the first sums of the two sheared coordinates.
    """
    count, nxt = cursor[0], cursor[1]
    while nxt < join.shape[0] and j_lo[join[nxt]] <= j:
        r = join[nxt]
        slots[0, count], slots[1, count], slots[2, count] = ray_ids[r], j_hi[r], 0
        slots[3, count] = base_a[r]
        slots[4, count] = base_b[r]
        count += 1
        nxt += 1
    kp, a_ax, b_ax = axes[0], axes[1], axes[2]
    q, off_a, off_b = order[j], offsets[j, 0], offsets[j, 1]
    sheared = slots[3:5].view(np.float64)
    p = np.empty(3)  # one sample's z, y, x
    kept = 0
    m = 0
    for t in range(count):
        ray = slots[0, t]
        if slots[1, t] < j or not alive[ray]:
            continue  # leaves the active set
        if kept != t:
            for c5 in range(5):
                slots[c5, kept] = slots[c5, t]
        kept += 1
        if j < slots[2, kept - 1]:
            continue  # inside a leap: an unoccupied block's run
        # SamplePlan.position, shear-warp: the same terms in the same order
        # (the slot holds its first sum, ``row + base_origin[0]``).
        p[kp] = q
        p[a_ax] = sheared[0, kept - 1] + off_a
        p[b_ax] = sheared[1, kept - 1] + off_b
        bz = np.int64(min(max(p[0], 0.0), vol_hi[0])) >> block_shift
        by = np.int64(min(max(p[1], 0.0), vol_hi[1])) >> block_shift
        bx = np.int64(min(max(p[2], 0.0), vol_hi[2])) >> block_shift
        c = distance[bz, by, bx]
        if c > 0:
            # Opacity 0 whatever the sample interpolates to, and so for the next
            # floor(((c - 1) block - 1e-6) / |delta|_inf) steps (SamplePlan.leap's bound).
            slots[2, kept - 1] = j + 1 + np.int64(np.floor((c - 1) * leap_per_block))
            continue
        zyx[m, 0], zyx[m, 1], zyx[m, 2] = p[0], p[1], p[2]
        rays[m] = ray
        m += 1
    cursor[0], cursor[1] = kept, nxt
    return m


def run_steps_compiled(
    plan: SamplePlan,
    blocks: Occupancy,
    kernel,
    state: RayState,
    stopped: np.ndarray,
    progress: Callable[[int, int], None] | None,
) -> int:
    """Composite every step of ``plan`` into ``state`` with ``kernel``
    (:class:`models.fused.CompositeKernel`), skipping samples in unoccupied ``blocks``;
    fills ``stopped`` as :meth:`models.functional._Functional._run_leapt` does and
    returns the samples simulated."""
    table = kernel.table(plan._dt)
    has_samples = plan.j_lo <= plan.j_hi
    join = np.flatnonzero(has_samples)[np.argsort(plan.j_lo[has_samples], kind="stable")]
    distance = np.ascontiguousarray(blocks.distance, dtype=np.int64)
    reach = float(np.max(np.abs(plan._delta)))
    # Steps per block of distance: (c - 1) * leap_per_block below SamplePlan.leap's
    # floor(((c - 1) block - 1e-6) / reach) for every c >= 1 (so never farther).
    leap_per_block = (blocks.block - 1e-6) / reach
    axes = np.array([plan.principal_axis, *plan.other_axes], dtype=np.int64)
    vol_hi = plan.n - 1.0
    block_shift = int(blocks.block).bit_length() - 1
    if 1 << block_shift != blocks.block:
        raise ValueError(f"occupancy block {blocks.block} is not a power of two")
    # The first sum of each position term, as SamplePlan.position forms it.
    ids = plan.ray_ids
    base_a = (ids // plan.shape[1] + plan.base_origin[0]).view(np.int64)
    base_b = (ids % plan.shape[1] + plan.base_origin[1]).view(np.int64)
    n = max(plan.ray_ids.size, 1)
    slots = np.empty((5, n), dtype=np.int64)
    cursor = np.zeros(2, dtype=np.int64)
    zyx = np.empty((n, 3))
    rays = np.empty(n, dtype=np.int64)
    stops = kernel.ert_thr >= 0
    simulated = 0
    for j in range(plan.n_steps):
        m = _step(
            j, plan.order, plan.offsets, base_a, base_b, axes, plan.j_lo, plan.j_hi,
            plan.ray_ids, join, cursor, slots, state.alive, distance, block_shift,
            leap_per_block, vol_hi, zyx, rays,
        )  # fmt: skip
        if m:
            step = Step(rays[:m], zyx[:m], plan._dt)
            kernel.run(step, None, state, table)
            simulated += m
            if stops:
                kept = rays[:m]
                stopped[kept[~state.alive[kept]]] = j
        if progress is not None:
            progress(j + 1, plan.n_steps)
    return simulated
