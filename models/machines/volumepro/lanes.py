"""Which pipeline evaluates each sample, and where a voxel lives, as the VolumePro family's
transaction rung counts them (the lane rule of docs/cycle.md's rule 4, written again from
the plan's positions; the mini-block layout refused for other skews).
"""

from __future__ import annotations

import numba
import numpy as np

from hwsim.core.errors import NotAvailableError
from hwsim.golden.positions import SamplePlan
from hwsim.memory import MemoryConfig
from models.machines.volumepro.memory import layout

__all__ = ["busiest_lanes", "live_lanes", "miniblock_layout", "sample_lanes"]


def miniblock_layout(memory: MemoryConfig, n: int, x, y, z):
    """Module, bank and word address of voxels ``(x, y, z)`` of an ``n``-cube (``n``
    even) in ``memory``'s mini-block layout: the cycle model's own
    (:func:`models.machines.volumepro.memory.layout`), refused for other skews."""
    if memory.skew not in ("miniblock", "block"):
        raise NotAvailableError(
            f"the transaction model reads mini-blocks; skew {memory.skew!r} is not modelled",
            key="memory.skew",
            allowed="miniblock, block",
        )
    return layout(memory, n, x, y, z)


def sample_lanes(zyx: np.ndarray, axes: tuple[int, int, int], shape, pipelines: int):
    """The pipeline evaluating each sample of one step at positions ``zyx``: the module
    ``(q + a + b) mod P`` of the skewed memory holding its nearest voxel, where ``q`` is
    the voxel slice nearest the step's sample slice and ``(a, b)`` the in-slice voxel
    nearest the sample (``cell + (fraction >= 1/2)``), each clamped to the volume;
    ``axes``: ``(k, a, b)``.  The cycle rung's rule (``SlabMachine._slots``) written
    again from the plan's positions; a slice lasts at least its busiest pipeline's
    sample count (docs/cycle.md, the VolumePro family, rule 4)."""
    kp, a_ax, b_ax = axes
    if not len(zyx):
        return np.zeros(0, dtype=np.int64)
    pk = float(zyx[0, kp])  # every sample of a step lies on its sample slice
    q = int(min(max(np.floor(pk + 0.5), 0), shape[kp] - 1))
    near = []
    for ax in (a_ax, b_ax):
        p = zyx[:, ax]
        c = np.floor(p)
        near.append(np.clip(c.astype(np.int64) + (p - c >= 0.5), 0, shape[ax] - 1))
    return (q + near[0] + near[1]) % pipelines


def busiest_lanes(plan: SamplePlan, pipelines: int) -> np.ndarray:
    """Samples of the busiest pipeline at each step of ``plan``, every planned sample
    counted with :func:`sample_lanes` at its position (the compiled walker's,
    :func:`models.fused_steps.plan_positions`): a shear-image plan's rays are not one per
    voxel column, so its lanes are not loaded evenly."""
    from models import fused_steps  # imports numba: only for the frames that need it

    kp = plan.principal_axis
    axes = (kp, *(ax for ax in range(3) if ax != kp))
    return fused_steps.busiest_lanes(
        plan, pipelines, lambda zyx: sample_lanes(zyx, axes, plan.volume.shape, pipelines)
    )


@numba.njit(cache=True, nogil=True)
def live_lanes(rays, alive, ert, history, lanes, skipping, live, known, busy):  # pragma: no cover
    """The cycle rung's per-step lane counts (``SlabMachine.run``) in one pass over a
    step's samples: ``live`` (``alive[rays]`` with ``ert``, else True), ``known``
    (``history[rays]`` when ``history`` has rays, else True) and ``busy``, the samples
    per lane (``bincount(lanes[live] if skipping else lanes, minlength=P)``, P =
    ``busy.size``).  Returns False, counting nothing more, at a lane outside ``[0, P)``."""
    busy[:] = 0
    use_known = history.size > 0
    for i in range(rays.size):
        r = rays[i]
        on = alive[r] if ert else True
        live[i] = on
        known[i] = history[r] if use_known else True
        lane = lanes[i]
        if lane < 0 or lane >= busy.size:
            return False
        if on or not skipping:
            busy[lane] += 1
    return True
