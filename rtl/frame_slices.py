"""The geometry unit's tables the host writes for the RTL top (:mod:`rtl.frame`): the
ray table and the per-slice constants, read off the plan (the geometry unit's output)
and *checked* against it: every sample the hardware will take (one per slot, the sample
whose nearest voxel is the slot's voxel) must be exactly the plan's samples of that
step, with the same cells and quantised weights; the gradient's in-slice neighbours must
sit in the adjacent slots; the crop box's slabs must be ranges of cells; a ray's samples
must be far enough apart for the compositing buffer's read-modify-write.  What fails is
refused naming ``view`` (another view) or ``volume``.

# Ref: architectures.md section 1 (Cube-4: the per-slice constants of a parallel
#      projection); docs/rtl.md (the host's writes).
"""

from __future__ import annotations

import numpy as np

from hwsim.core.errors import InputError
from hwsim.golden.positions import SamplePlan
from models.datapath import Datapath
from models.machines.cube4.frame import Cube4Frame
from rtl.frame_tables import pack_fields
from rtl.top import RMW_WINDOW
from rtl.top_layouts import LOAD_RAYS, LOAD_SLICES, TopGeometry, ray_layout, slice_layout

__all__ = ["geometry_loads", "refuse", "slice_constants"]


def refuse(message: str, key: str, allowed: str, source=None) -> InputError:
    """The host's refusal: one :class:`InputError` naming ``key`` and what is allowed."""
    return InputError(message, source=source, key=key, allowed=allowed)


def geometry_loads(
    machine: Cube4Frame, plan: SamplePlan, geo: TopGeometry, dp: Datapath, crop=None
) -> list[tuple[int, int, int]]:
    """The geometry unit's loads: the ray table (first and last step of every base-plane
    ray; ``never`` for unused ones) and the per-slice constants (:func:`slice_constants`)."""
    n_rays = plan.shape[0] * plan.shape[1]
    rlay = ray_layout(geo)
    never = (1 << geo.axis_bits) - 1
    j_lo = np.full(n_rays, never, dtype=np.int64)
    j_hi = np.zeros(n_rays, dtype=np.int64)
    j_lo[plan.ray_ids], j_hi[plan.ray_ids] = plan.j_lo, plan.j_hi
    loads = [
        (LOAD_RAYS, r, pack_fields(rlay, {"j_lo": j_lo[r], "j_hi": j_hi[r]})) for r in range(n_rays)
    ]
    slices = slice_constants(machine, plan, j_lo, j_hi, crop)
    slay = slice_layout(geo, dp)
    return loads + [(LOAD_SLICES, j, pack_fields(slay, rec)) for j, rec in enumerate(slices)]


def _canonical(cell, weight, frac, full: int):
    """A weight that quantised to exactly 1.0 in cell ``c`` is weight 0 in cell ``c + 1``:
    ``lerp(a, b, 2**W) = b = lerp(b, c, 0)`` exactly, in every rounding mode (no
    remainder).  Float positions a hair below an integer (``frac`` ~ 1.0) thus get the
    same constants as their neighbours on the integer."""
    up = weight == full
    if not up.any():
        return cell, weight, frac
    return cell + up, np.where(up, 0, weight), np.where(up, 0.0, frac)


def _check_neighbours(machine: Cube4Frame, step, j: int, full: int) -> None:
    """The gradient's in-slice neighbours (positions ``p +- 1`` along each in-slice axis,
    the cells and weights the cycle rung gives them) must be the cells next to the
    sample's with the sample's own weight: the top reads them off the neighbouring slots."""
    for axis in (machine.a_ax, machine.b_ax):
        p = step.zyx[:, axis]
        own = machine.cell(p)
        cell, weight, _ = _canonical(*own, full)
        for shift in (1.0, -1.0):
            n_cell, n_weight, _ = _canonical(*machine.cell(p + shift, own), full)
            if not (np.all(n_cell - cell == int(shift)) and np.array_equal(n_weight, weight)):
                raise refuse(
                    f"step {j}: a gradient neighbour's weight differs from its sample's "
                    "(float rounding of p +- 1); the RTL top takes neighbours from the "
                    "adjacent slots",
                    "view",
                    "another view",
                )


def _crop_slabs(machine: Cube4Frame, step, j: int, cells, crop) -> dict[str, int]:
    """The crop box's slabs on step ``j``: whether the slice is inside the principal
    axis's slab, and per in-slice axis the cells whose samples (the plan's positions) are
    inside its slab, checked sample by sample (float positions one step's samples
    disagree on are refused naming ``view``)."""
    out = {"crop_k": 1}
    every = (-2, max(machine.n_a, machine.n_b) + 1)  # an axis without limits: every cell
    axes = (machine.a_ax, machine.b_ax)
    k_col = next(c for c in range(3) if c not in axes)
    limits = {0: crop.z, 1: crop.y, 2: crop.x} if crop is not None else {}
    for col, name in ((k_col, "k"), (axes[0], "a"), (axes[1], "b")):
        if name != "k":
            out[f"crop_{name}_lo"], out[f"crop_{name}_hi"] = every
        if limits.get(col) is None:
            continue
        lo, hi = limits[col]
        p = step.zyx[:, col]
        inside = (p >= lo) & (p <= hi)
        if name == "k":
            if np.unique(inside).size > 1:
                raise refuse(f"step {j}: the crop box cuts the slice", "view", "another view")
            out["crop_k"] = int(inside[0])
            continue
        c = cells[name]
        lo_c, hi_c = (int(c[inside].min()), int(c[inside].max())) if inside.any() else (1, 0)
        if not np.array_equal(inside, (c >= lo_c) & (c <= hi_c)):
            raise refuse(
                f"step {j}: the crop box's {name} slab is not a range of cells (float rounding)",
                "view",
                "another view",
            )
        out[f"crop_{name}_lo"], out[f"crop_{name}_hi"] = lo_c, hi_c
    return out


def slice_constants(
    machine: Cube4Frame, plan: SamplePlan, j_lo, j_hi, crop=None
) -> list[dict[str, int]]:
    """Per step: slice, cell shift, base-plane offset and weights, the crop box's slabs,
    checked sample by sample against the plan (the hardware's slot rule must give
    exactly its samples)."""
    P, C, T = machine.P, machine.C, machine.T
    n_a, n_b = machine.n_a, machine.n_b
    W = plan.shape[1]
    a = np.repeat(np.arange(n_a), n_b)
    b = np.tile(np.arange(n_b), n_a)
    period = T  # slices back to back (prepare refuses an overhead)
    last_issue = np.full(plan.shape[0] * W, -(10**9), dtype=np.int64)
    out = []
    for j, step in enumerate(plan.steps()):
        q = machine.slice_of(j)
        rec = {"q": q, "qm": q % P, "da": 0, "db": 0, "ia": 0, "ib": 0, "wa": 0, "wb": 0}
        rec.update(crop_k=0, crop_a_lo=0, crop_a_hi=0, crop_b_lo=0, crop_b_hi=0)
        rays = step.rays
        if rays.size:
            full = 1 << machine.dp.interp.weight_bits
            ca, wa, fa = _canonical(*machine.cell(step.zyx[:, machine.a_ax]), full)
            cb, wb, fb = _canonical(*machine.cell(step.zyx[:, machine.b_ax]), full)
            _check_neighbours(machine, step, j, full)
            u, v = rays // W, rays % W
            uniform = all(
                np.unique(x).size == 1 for x in (wa, wb, fa >= 0.5, fb >= 0.5, ca - u, cb - v)
            )
            if not uniform:
                raise refuse(
                    f"step {j}: the plan's weights or cell offsets differ between rays (float "
                    "rounding); the RTL top takes one set of constants per slice",
                    "view",
                    "another view",
                )
            rec.update(
                da=int(fa[0] >= 0.5),
                db=int(fb[0] >= 0.5),
                ia=int(ca[0] - u[0]),
                ib=int(cb[0] - v[0]),
                wa=int(wa[0]),
                wb=int(wb[0]),
            )
            rec.update(_crop_slabs(machine, step, j, {"a": ca, "b": cb}, crop))
        # The hardware's samples: one per slot voxel, the cell whose nearest voxel it is.
        hu = a - rec["da"] - rec["ia"]
        hv = b - rec["db"] - rec["ib"]
        inside = (hu >= 0) & (hu < plan.shape[0]) & (hv >= 0) & (hv < W)
        ray = np.where(inside, hu * W + hv, 0)
        takes = inside & (j_lo[ray] <= j) & (j <= j_hi[ray])
        hw = np.sort(ray[takes])
        if not np.array_equal(hw, np.sort(rays)):
            raise refuse(
                f"step {j}: {rays.size} samples in the plan, {hw.size} slots would take one "
                "(a sample exactly half a voxel beyond the volume shares its slot)",
                "view",
                "another view",
            )
        # Read-modify-write distance on the compositing buffer between a ray's samples.
        issue = (j + 1) * period + a * C + b // P
        issue = issue[takes]
        gap = issue - last_issue[ray[takes]]
        if gap.size and gap.min() < RMW_WINDOW:
            raise refuse(
                f"step {j}: a ray's samples {gap.min()} clocks apart, the compositing "
                f"buffer needs {RMW_WINDOW}",
                "volume",
                "a larger volume",
            )
        last_issue[ray[takes]] = issue
        out.append(rec)
    return out
