"""The functional rung's compiled step walker.

# Ref: Lacroute & Levoy, SIGGRAPH 1994 (shear-warp: one sample per base-plane pixel per
#      slice); architectures.md section 3 (VolumePro 1000's shear-image order: rays
#      through pixel centres, samples on voxel slices); hwsim/golden/steps.py (the step
#      engine this replaces for such frames);
#      docs/fidelity.md ("How the functional rung simulates fast, exactly").

:func:`models.functional._Functional.run` walks a frame's steps with
:func:`hwsim.golden.steps.run_steps` over a plan shortened by
:meth:`~hwsim.golden.positions.SamplePlan.leap`: NumPy calls per step for the active
set, the positions and the chunks, and a leap march per frame.  On a 256^3 frame that
bookkeeping costs as much as half the compiled composite stage.  Here one compiled call
per step does it for a shear-warp, shear-image or ray plan:

* the *active set* is kept as in ``run_steps``: rays join at their ``j_lo``, leave after
  their ``j_hi`` or when early termination cleared their ``alive`` flag;
* each active ray's position is the float expression of
  :meth:`SamplePlan.position <hwsim.golden.positions.SamplePlan.position>` for a
  plan of that kind, term for term and in the same order (the terms
  that do not depend on the step formed once per ray), so the samples are the same
  floats (``tests/models/test_functional_fused.py`` compares the frames);
* a sample whose block (:data:`~hwsim.golden.occupancy.BLOCK` voxels, position clamped to
  the volume) is not occupied in :func:`models.leap.invisible_blocks` is skipped: its
  trilinear value lies in that block's range, which classifies to opacity 0, so the
  composite stage would drop it unchanged.  This is the same exact argument as the
  plan's leap, applied per sample, so it also skips empty runs inside a ray;
* in an occupied block, a sample whose cell is *clear* (:func:`clear_cells`: the
  2 x 2 x 2 voxels it interpolates classify to opacity 0 whatever their mix) is skipped
  too: the same argument per cell.  On the VolPack benchmark's MR frames half the
  samples in occupied blocks are transparent and half of those lie in clear cells: the
  kernel gets 1.00 M samples a frame instead of 1.32 M.

The samples kept in a step go to :class:`models.fused.CompositeKernel` as one part; each
ray is at most once in a step, so the kernel's order-free blend holds.  What the machine
visits (``samples``, touched rays) is recounted from the full plan by
:func:`models.leap.visits`, as on the leapt path.

**Scope.**  Frames the composite kernel runs (:func:`models.fused.eligible`) on a
shear-warp, shear-image or ray plan whose samples share a step length with a correction
table (parallel views; ray plans in perspective too), without crop box or cut
planes (their masks stay in :meth:`models.backend.Backend.masks`): :func:`applies`.
"""

from __future__ import annotations

import hashlib
import weakref
from collections.abc import Callable, Iterator

import numba
import numpy as np

from hwsim.core import interrupt
from hwsim.core.threads import frame_threads
from hwsim.core.threads import pool as thread_pool
from hwsim.golden.occupancy import Occupancy
from hwsim.golden.positions import SamplePlan
from models.backend import Backend, RayState
from models.units import classify as classify_unit

__all__ = ["applies", "busiest_lanes", "plan_positions", "position_terms", "run_steps_compiled"]


def applies(backend: Backend, plan: SamplePlan, kernel, blocks: Occupancy | None) -> bool:
    """Whether :func:`run_steps_compiled` can walk ``plan`` for ``backend``."""
    scene = backend.scene
    return (
        kernel is not None
        and blocks is not None
        and plan.kind in ("shear-warp", "shear-image", "ray")
        and scene.crop is None
        and not scene.cut_planes
        and kernel.table(plan._dt) is not None
    )


#: ``_step``'s plan kinds.
_SHEAR_WARP, _SHEAR_IMAGE, _RAY = 0, 1, 2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _step(
    j, kind, q_of_step, offsets, ss, k_first, k_dir, dt, axes, ray_ids, ray_cols, j_lo, j_hi, join,
    cursor, slots, terms, alive, distance, block_shift, vol_hi, cells, cell_strides, zyx, rays,
):  # fmt: skip
    """Step ``j``'s kept samples into ``zyx`` and ``rays``; returns how many.

    ``join`` lists plan rays by ascending ``j_lo`` (rays with samples only); ``cursor``
    holds the active count and the next ray to join.  The active rays are columns of
    ``slots`` (ray id, last step, first step not leapt) and ``terms`` (their position
    terms, :func:`_ray_terms`, and the steps leapt per block of distance), read in order;
    rays that left are compacted out in place once they are an eighth of the set (until
    then the step skips them: the samples and their order are the same), and
    ``ray_cols`` holds the same per plan ray, ready to join.
    """
    count, nxt = cursor[0], cursor[1]
    while nxt < join.shape[0] and j_lo[join[nxt]] <= j:
        r = join[nxt]
        slots[0, count], slots[1, count], slots[2, count] = ray_ids[r], j_hi[r], 0
        for c in range(terms.shape[0]):
            terms[c, count] = ray_cols[c, r]
        count += 1
        nxt += 1
    kp = axes[0]
    off_a, off_b = offsets[j, 0], offsets[j, 1]
    j_ss = np.float64(j) / ss
    t_ray = np.float64(k_first + k_dir * j) * dt
    m = 0
    dead = 0
    for k in range(count):
        ray = slots[0, k]
        if slots[1, k] < j or not alive[ray]:
            dead += 1
            continue  # left the active set
        if j < slots[2, k]:
            continue  # inside a leap: an unoccupied block's run
        # SamplePlan.position: the same terms in the same order.
        if kind == _RAY:  # terms: o, then d (z, y, x)
            pz = terms[0, k] + t_ray * terms[3, k]
            py = terms[1, k] + t_ray * terms[4, k]
            px = terms[2, k] + t_ray * terms[5, k]
        else:
            if kind == _SHEAR_WARP:  # terms: row + base_origin[0], column + base_origin[1]
                pk = q_of_step[j]
                pa = terms[0, k] + off_a
                pb = terms[1, k] + off_b
            else:  # terms: q0, sign, o and d along kp, a, b
                pk = terms[0, k] + terms[1, k] * j_ss
                along = (pk - terms[2, k]) / terms[3, k]
                pa = terms[4, k] + along * terms[5, k]
                pb = terms[6, k] + along * terms[7, k]
            # The axes: kp, then the other two ascending.
            if kp == 0:
                pz, py, px = pk, pa, pb
            elif kp == 1:
                pz, py, px = pa, pk, pb
            else:
                pz, py, px = pa, pb, pk
        iz = np.int64(min(max(pz, 0.0), vol_hi[0]))
        iy = np.int64(min(max(py, 0.0), vol_hi[1]))
        ix = np.int64(min(max(px, 0.0), vol_hi[2]))
        c = distance[iz >> block_shift, iy >> block_shift, ix >> block_shift]
        if c > 0:
            # Opacity 0 whatever the sample interpolates to, and so for the next
            # floor(((c - 1) block - 1e-6) / |delta|_inf) steps (SamplePlan.leap's bound).
            slots[2, k] = j + 1 + np.int64(np.floor((c - 1) * terms[terms.shape[0] - 1, k]))
            continue
        if cells[iz * cell_strides[0] + iy * cell_strides[1] + ix * cell_strides[2]]:
            continue  # a clear cell: opacity 0 whatever the sample interpolates to
        zyx[m, 0], zyx[m, 1], zyx[m, 2] = pz, py, px
        rays[m] = ray
        m += 1
    if 8 * dead > count:  # compact
        kept = 0
        for t in range(count):
            if slots[1, t] < j or not alive[slots[0, t]]:
                continue
            if kept != t:
                for c in range(3):
                    slots[c, kept] = slots[c, t]
                for c in range(terms.shape[0]):
                    terms[c, kept] = terms[c, t]
            kept += 1
        count = kept
    cursor[0], cursor[1] = count, nxt
    return m


def _axes(plan: SamplePlan) -> tuple[int, int, int]:
    """The principal axis, then the other two in ascending order (z, y, x for a ray
    plan without one: its positions do not use them)."""
    kp = 0 if plan.principal_axis is None else plan.principal_axis
    return (kp, *(a for a in range(3) if a != kp))


def _ray_terms(plan: SamplePlan, block: int, *, leap: bool = True) -> np.ndarray:
    """Per plan ray, the terms of its positions that do not depend on the step (formed
    as :meth:`SamplePlan.position <hwsim.golden.positions.SamplePlan.position>` forms
    them), then the steps it may leap per block of chessboard distance:
    ``(c - 1) (block - 1e-6) / |delta|_inf``, never beyond the plan leap's
    ``floor(((c - 1) block - 1e-6) / |delta|_inf)`` for any ``c >= 1``.  ``leap``
    False: a shear-image plan's eight position terms alone, without the leap row."""
    kp, a_ax, b_ax = _axes(plan)
    n = plan.ray_ids.size
    if not leap and plan.kind == "shear-image":
        o, d = plan._o, plan._d
        cols = [plan._q0, plan._sign, o[:, kp], d[:, kp], o[:, a_ax], d[:, a_ax]]
        return np.ascontiguousarray(np.stack([*cols, o[:, b_ax], d[:, b_ax]]), dtype=np.float64)
    delta = np.asarray(plan._delta, dtype=np.float64)
    if delta.ndim == 1:  # one step for every ray (a parallel view): one quotient
        leap = np.full(n, (block - 1e-6) / np.max(np.abs(delta)))
    else:
        leap = (block - 1e-6) / np.max(np.abs(np.broadcast_to(delta, (n, 3))), axis=1)
    if plan.kind == "shear-warp":  # row + base_origin[0], column + base_origin[1]
        terms = np.empty((3, n))
        row, col = np.divmod(plan.ray_ids, plan.shape[1])
        np.add(row, plan.base_origin[0], out=terms[0])
        np.add(col, plan.base_origin[1], out=terms[1])
        terms[2] = leap
        return terms
    elif plan.kind == "ray":
        o, d = plan._o, np.broadcast_to(plan._d, (n, 3))
        cols = [o[:, 0], o[:, 1], o[:, 2], d[:, 0], d[:, 1], d[:, 2]]
    else:
        o, d = plan._o, plan._d
        cols = [
            plan._q0,
            plan._sign,
            o[:, kp],
            d[:, kp],
            o[:, a_ax],
            d[:, a_ax],
            o[:, b_ax],
            d[:, b_ax],
        ]
    return np.ascontiguousarray(np.stack([*cols, leap]), dtype=np.float64)


#: No clear-cell map: every cell reads 0 (one entry, strides 0).
_NO_CELLS = (np.zeros(1, dtype=np.uint8), np.zeros(3, dtype=np.int64))
#: Cells of a volume up to which :func:`clear_cells` keeps a map (a byte per voxel).
_CELL_MAP_VOXELS = 1 << 25
#: Per volume: the clear-cell maps, by layout and classification.
_CELLS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@numba.njit(cache=True, nogil=True)
def _clear_cell_map(vox, shape, strides, order, v_min, index, next_visible, out):
    """``out[cell] = 1`` where no LUT entry between the indices of the cell's smallest and
    largest voxel (``i`` and ``i + 1`` along each axis, clamped to the volume) has
    non-zero opacity; ``index[v - v_min]`` is raw voxel ``v``'s LUT index, promoted
    (see :func:`clear_cells`).  Cells are visited in memory order (``order``: the axes,
    slowest first)."""
    n0, n1, n2 = shape[order[0]], shape[order[1]], shape[order[2]]
    s0, s1, s2 = strides[order[0]], strides[order[1]], strides[order[2]]
    for a in range(n0):
        a1 = (min(a + 1, n0 - 1) - a) * s0
        for b in range(n1):
            b1 = (min(b + 1, n1 - 1) - b) * s1
            row = a * s0 + b * s1
            for c in range(n2):
                c1 = (min(c + 1, n2 - 1) - c) * s2
                base = row + c * s2
                lo = hi = np.int64(vox[base])
                for da in (0, a1):
                    for db in (0, b1):
                        for dc in (0, c1):
                            v = np.int64(vox[base + da + db + dc])
                            lo, hi = min(lo, v), max(hi, v)
                out[base] = next_visible[index[lo - v_min]] > index[hi - v_min]


def clear_cells(kernel) -> tuple[np.ndarray, np.ndarray] | None:
    """The cells of ``kernel``'s volume (:class:`models.fused.CompositeKernel`) whose every
    sample classifies to opacity 0, as a byte per cell laid out as the kernel's voxels
    (its strides returned with it); None above :data:`_CELL_MAP_VOXELS`.

    The same exact argument as the block leap (:mod:`models.leap`) on the 2 x 2 x 2
    voxels a sample interpolates: the trilinear sample lies in their promoted range and
    the LUT index is non-decreasing in it, so no entry between the range's ends with
    non-zero opacity means opacity 0 (gradient modulation only scales it).  A cell
    ``i`` holds the samples with ``floor(p) = i`` (position clamped to the volume, as
    the walker clamps it): ``interp.cell_weight`` reads voxels ``i`` and ``i + 1``, or at
    the last voxel ``i - 1`` and ``i`` with weight 1.0, which gives voxel ``i`` exactly.
    Kept per volume, layout and classification (successive frames of a turntable); a
    layout whose classification another layout of the volume holds copies that map
    (:func:`_relaid`: the principal axis moved) instead of a pass over the voxels."""
    be, vox = kernel.backend, kernel.vox
    if vox.size > _CELL_MAP_VOXELS or vox.size == 0:
        return None
    s_bits, _, _, lut_shift, entries = kernel.config[:5]
    next_visible = np.ascontiguousarray(be.transparent_ranges(), dtype=np.int64)
    layout = (be.dp.voxel_bits, vox.dtype.str, tuple(int(s) for s in kernel.strides))
    key = (s_bits, lut_shift, entries, hashlib.sha256(next_visible.tobytes()).hexdigest())
    maps = _CELLS.setdefault(be.volume, {})  # per layout: (classification, map)
    if maps.get(layout, (None,))[0] != key:
        for (bits, dtype, _), (their_key, (cells, strides)) in list(maps.items()):
            if (bits, dtype, their_key) == (layout[0], layout[1], key):
                # The same cells in another memory order (the principal axis moved):
                # the map is a function of each cell's voxels, so it is laid out anew.
                out = _relaid(cells, strides, kernel.shape, kernel.strides)
                maps[layout] = (key, (out, kernel.strides.copy()))
                return maps[layout][1]
        v_min, v_max = int(vox.min()), int(vox.max())
        # Each raw value's LUT index, by the unit's own arithmetic (promoted as read).
        values = np.arange(v_min, v_max + 1, dtype=np.int64)
        index = classify_unit.lut_index_raw(values << s_bits, lut_shift, entries)
        out = np.zeros(vox.size, dtype=np.uint8)
        order = np.argsort(-kernel.strides, kind="stable")
        _clear_cell_map(vox, kernel.shape, kernel.strides, order, v_min, index, next_visible, out)
        maps[layout] = (key, (out, kernel.strides.copy()))  # one classification a layout
    return maps[layout][1]


def _relaid(cells: np.ndarray, strides: np.ndarray, shape, new_strides) -> np.ndarray:
    """A byte per cell of a ``shape`` volume laid out with element ``strides`` (z, y,
    x), copied into the layout of ``new_strides``."""
    shape = tuple(int(n) for n in shape)
    source = np.lib.stride_tricks.as_strided(cells, shape, tuple(int(s) for s in strides))
    out = np.empty(cells.size, dtype=np.uint8)
    target = np.lib.stride_tricks.as_strided(out, shape, tuple(int(s) for s in new_strides))
    target[...] = source
    return out


class _Walker:
    """One plan's step walk: the static arguments of :func:`_step` and its buffers."""

    def __init__(
        self,
        plan: SamplePlan,
        distance: np.ndarray,
        block: int,
        mine: np.ndarray | None = None,
        cells: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """``mine``: which plan rays this walker walks (a boolean per plan ray; all when
        None); ``cells``: the clear-cell map and its strides (:func:`clear_cells`), or
        None."""
        block_shift = int(block).bit_length() - 1
        if 1 << block_shift != block:
            raise ValueError(f"occupancy block {block} is not a power of two")
        sheared = plan.kind == "shear-warp"
        has_samples = plan.j_lo <= plan.j_hi
        if mine is not None:
            has_samples &= mine
        join = np.flatnonzero(has_samples)[np.argsort(plan.j_lo[has_samples], kind="stable")]
        ray_cols = _ray_terms(plan, block)
        n = max(plan.ray_ids.size, 1)
        self.plan = plan
        #: The step's samples: positions and ray ids (the first ``m`` rows).
        self.zyx, self.rays = np.empty((n, 3)), np.empty(n, dtype=np.int64)
        #: The step length (one value: ray plans read it for their positions).
        self.dt = plan._dt if np.isscalar(plan._dt) else float(plan._dt.flat[0])
        self._before = (
            {"shear-warp": _SHEAR_WARP, "shear-image": _SHEAR_IMAGE, "ray": _RAY}[plan.kind],
            plan.order if sheared else np.zeros(1),
            plan.offsets if sheared else np.zeros((plan.n_steps, 2)),
            float(plan.scene.render.supersampling),
            int(getattr(plan, "k_first", 0)),
            int(getattr(plan, "k_dir", 1)),
            self.dt,
            np.array(_axes(plan), dtype=np.int64),
            plan.ray_ids,
            ray_cols,
            plan.j_lo,
            plan.j_hi,
            join,
            np.zeros(2, dtype=np.int64),  # cursor
            np.empty((3, n), dtype=np.int64),  # slots
            np.empty((ray_cols.shape[0], n)),  # terms
        )
        self._after = (
            np.ascontiguousarray(distance, dtype=np.int64),
            block_shift,
            plan.n - 1.0,
            *(_NO_CELLS if cells is None else cells),
            self.zyx,
            self.rays,
        )

    def step(self, j: int, alive: np.ndarray) -> int:
        """Step ``j``'s kept samples into :attr:`zyx` and :attr:`rays`; returns how many."""
        return _step(j, *self._before, alive, *self._after)


#: Plan rays per block of a thread's share (:func:`run_steps_compiled`): rays next to
#: each other cost alike, so interleaved blocks balance the threads.
_RAY_BLOCK = 16


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
    returns the samples simulated.

    With :func:`~hwsim.core.threads.frame_threads` above one the plan's rays are dealt to the
    threads in interleaved blocks of :data:`_RAY_BLOCK`; each thread walks every step for
    its own rays (a ray's samples stay in order, in one thread), so the frame is the
    same bits for any thread count, and the threads meet only at the end."""
    table = kernel.table(plan._dt)
    n_rays = plan.ray_ids.size
    threads = min(frame_threads(), max(1, n_rays // (4 * _RAY_BLOCK)))
    if threads <= 1:
        share = [None]
    else:
        block = (np.arange(n_rays) // _RAY_BLOCK) % threads
        share = [block == k for k in range(threads)]
    stops = kernel.ert_thr >= 0
    no_factor = np.zeros(0, dtype=np.int64)
    cells = clear_cells(kernel)

    def walk_share(mine, report) -> tuple[int, np.ndarray]:
        walk = _Walker(plan, blocks.distance, blocks.block, mine, cells)
        simulated, sat = 0, np.zeros(3, dtype=np.int64)  # run_part: + settled
        for j in range(plan.n_steps):
            interrupt.check()  # Ctrl-C: the threads without progress stop here too
            m = walk.step(j, state.alive)
            if m:
                rays = walk.rays[:m]
                sat += kernel.run_part(walk.zyx[:m], rays, no_factor, state, table)
                simulated += m
                if stops:
                    stopped[rays[~state.alive[rays]]] = j
            if report is not None:
                report(j + 1, plan.n_steps)
        return simulated, sat

    if len(share) == 1:
        results = [walk_share(None, progress)]
    else:
        pool = thread_pool(threads)
        others = [pool.submit(walk_share, mine, None) for mine in share[1:]]
        results = [walk_share(share[0], progress)]  # this thread reports progress
        results += [f.result() for f in others]
    kernel.count_saturations(sum(sat for _, sat in results))
    return sum(simulated for simulated, _ in results)


def plan_positions(plan: SamplePlan) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """``(j, zyx, rays)`` for every step of ``plan`` with samples: the positions and ray
    ids of all its planned samples (no termination, no skipping), the same floats as
    :meth:`SamplePlan.position <hwsim.golden.positions.SamplePlan.position>`, in an
    order of the step's rays that is not the plan's.  Both arrays are reused between
    steps."""
    # One block covering the volume (shift 62), occupied: nothing is skipped.
    walk = _Walker(plan, np.zeros((1, 1, 1), dtype=np.int64), 1 << 62)
    alive = np.ones(int(plan.ray_ids.max(initial=0)) + 1, dtype=bool)
    for j in range(plan.n_steps):
        m = walk.step(j, alive)
        if m:
            yield j, walk.zyx[:m], walk.rays[:m]


def position_terms(plan: SamplePlan) -> tuple[np.ndarray, np.ndarray]:
    """The plan rays with samples by ascending ``j_lo`` (the walker's join order) and
    their eight position terms (:func:`_ray_terms` without the leap row): for loops that
    form :func:`plan_positions`' floats themselves
    (:func:`models.machines.volumepro.skips_kernel.plan_step_cells`)."""
    has_samples = plan.j_lo <= plan.j_hi
    join = np.flatnonzero(has_samples)[np.argsort(plan.j_lo[has_samples], kind="stable")]
    return join, _ray_terms(plan, 1 << 62, leap=False)


def busiest_lanes(plan: SamplePlan, pipelines: int, lanes_of) -> np.ndarray:
    """Samples of the busiest of ``pipelines`` lanes at each step of ``plan``, every
    planned sample counted (:func:`plan_positions`): ``lanes_of(zyx)``, the lanes of a
    step's sample positions by the machine's lane rule."""
    out = np.zeros(plan.n_steps, dtype=np.int64)
    for j, zyx, _ in plan_positions(plan):
        out[j] = np.bincount(lanes_of(zyx), minlength=pipelines).max()
    return out
