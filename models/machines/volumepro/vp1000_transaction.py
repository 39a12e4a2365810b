"""VolumePro 1000 as a SimPy event model: the slab machine with beam skipping.

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rule 6 (skipping: clock groups of
#      live rays, mini-blocks of live cells, the sequencer's lagged termination mask);
#      architectures.md section 4 (VolumePro 1000: early ray termination, shear-image
#      order, perspective; Wu et al., I3D 2003).

VolumePro 1000 skips work two ways (docs/cycle.md rule 6): a beam costs one clock per
*clock group* (``P`` consecutive cells) holding a sample of a live ray, and the memory
reads only the mini-blocks some live cell's trilinear window and gradient neighbours
touch, deciding with the termination mask of ``ceil(4 x supersampling)`` sample slices
earlier (it reads up to two slabs ahead).  Space leaping shortens the rays' sample ranges
past blocks the classification makes empty.

This module supplies what the event model of :mod:`models.machines.volumepro.transaction` needs for
that, at beam and mini-block granularity (:class:`BeamSkips`):

* which rays are alive at each slice comes from the **functional rung**: its per-ray
  termination step (:attr:`models.functional.FunctionalResult.stopped`, the step of each
  ray's last live sample), so no compositing is repeated here;
* where the live rays are: the plan's sample cells at each slice (positions only; no
  voxel is read, interpolated or classified);
* empty space: the leaped plan, built from the volume and the fixed-point LUT with the
  shared helpers the cycle rung uses (:func:`hwsim.golden.occupancy.block_ranges`,
  :func:`~hwsim.golden.occupancy.occupancy_from_ranges`,
  :meth:`models.backend.Backend.transparent_ranges`).

The clock is then :class:`models.machines.volumepro.transaction.SlabTransaction`'s: beam groups and
chunks of mini-block beams, the shared SDRAM transaction port for the bursts actually
read.  What is coarser than the cycle rung: readiness and freeing per chunk (as VolumePro
500) and a chunk's buffer slot counted whole even when most of its mini-blocks are skipped.

Each slice's busiest pipeline (what stretches a slice whose rays are denser than its
voxels, magnified perspective: docs/cycle.md rule 4) is counted, not estimated: a live
sample is evaluated by the pipeline of its nearest voxel, the skewed memory's module
``(q + a + b) mod P`` (:func:`~models.machines.volumepro.lanes.sample_lanes`, the
cycle rung's rule written again); several rays share a nearest voxel, so the ``P`` lanes
are not loaded evenly and a slice lasts as long as its busiest one.  An even split of
the live samples (``ceil(live / P)``, the model's earlier estimate) ran 2.1-4.7 % short
on magnified frames (head 40^3 in an 80 x 80 perspective view: -2.1 %).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hwsim.golden import geometry
from hwsim.golden.occupancy import occupancy_from_ranges
from hwsim.golden.positions import SamplePlan, make_plan
from models.backend import Backend
from models.frame import Frame
from models.machines.common.transaction import ReadsTheFrame, TxnTiming
from models.machines.volumepro.lanes import sample_lanes
from models.machines.volumepro.timing import mini_blocks_read
from models.machines.volumepro.transaction import SlabTransaction

__all__ = ["BeamSkips", "Vp1000Transaction", "beam_skips", "leaping_plan", "stopping_modes"]

#: Modes whose rays stop on a machine with ERT hardware (opacity threshold, iso's hit).
stopping_modes = ("composite", "iso")
#: Rays whose rule 6 loop state (:func:`_ray_state`) is kept for later frames, at most.
_KEEP_RAYS = 1 << 18  # 23 MB of terms, steps and cells
_rays_kept: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
_rays_lock = threading.Lock()


@dataclass
class BeamSkips:
    """Rule 6 at beam and mini-block granularity, for one frame.

    ``cost[j, a]``: clocks of beam ``a`` at sample slice ``j`` (clock groups holding a
    live sample; 0: the beam is skipped); ``needed[s, u, m]``: whether mini-block ``m``
    of mini-block beam ``u`` of slab ``s`` is read; ``live[j]``: live samples of slice
    ``j``; ``busiest[j]``: live samples of slice ``j``'s busiest pipeline
    (:func:`~models.machines.volumepro.lanes.sample_lanes`); ``stopped_rays``: rays
    that stopped before their last planned sample; ``leaped``: planned samples space
    leaping removed.
    """

    cost: np.ndarray
    needed: np.ndarray
    live: np.ndarray
    busiest: np.ndarray
    stopped_rays: int = 0
    leaped: int = 0


def leaping_plan(backend: Backend, plan: SamplePlan) -> SamplePlan:
    """``plan`` with every ray's first and last samples moved past blocks that cannot hold
    a visible sample *through this datapath's LUT* (the block's voxel range, and its +1
    neighbours', gives LUT indices whose entries all have opacity 0: lerps are convex).
    The cycle rung's rule (docs/cycle.md rule 6), with the same shared helpers."""
    be = backend
    occupancy = occupancy_from_ranges(be.occupied_blocks())
    return make_plan(be.scene, be.volume, plan.kind, occupancy=occupancy)


def beam_skips(
    plan: SamplePlan,
    pipelines: int,
    stopped: np.ndarray | None,
    lag: int,
    window,
    *,
    compiled: bool = True,
) -> BeamSkips:
    """Per-beam clocks and mini-blocks read at every sample slice of ``plan``.

    Parameters
    ----------
    plan : SamplePlan
        A ``shear-image`` plan (leaped when the machine leaps).
    pipelines : int
        ``P``: cells per clock group.
    stopped : ndarray or None
        Per accumulation ray, the step of its last live sample
        (:attr:`models.functional.FunctionalResult.stopped`); None: no ray stops.
    lag : int
        Sample slices between the termination mask the memory sequencer decides with
        and the slice being processed (``ceil(4 x supersampling)``).
    window : callable or ndarray
        ``window(j) -> (lo, hi)``: the slabs holding sample slice ``j``'s voxel window;
        or int64 ``(n_steps, 2)``, row ``j`` those slabs.
    compiled : bool
        Each slice's cells, clocks and lanes by the compiled loop
        (:func:`models.machines.volumepro.skips_kernel.frame_skips`); False: the NumPy
        form, its reference (the same results).
    """
    kp = plan.principal_axis
    a_ax, b_ax = (ax for ax in range(3) if ax != kp)
    shape = plan.volume.shape
    n_a, n_b, P = shape[a_ax], shape[b_ax], pipelines
    C = -(-n_b // P)
    n_u, n_mb = -(-n_a // 2), -(-n_b // 2)
    cost = np.zeros((plan.n_steps, n_a), dtype=np.int64)
    needed = np.zeros((-(-shape[kp] // 2), n_u, n_mb), dtype=bool)
    live_count = np.zeros(plan.n_steps, dtype=np.int64)
    busiest = np.zeros(plan.n_steps, dtype=np.int64)
    compiled = compiled and plan.kind == "shear-image"  # the compiled loop's positions
    if compiled:
        from models.machines.volumepro.skips_kernel import PACK_LIMIT  # numba

        compiled = max(shape) < PACK_LIMIT  # its packed cells
    if compiled:
        _compiled_skips(plan, P, stopped, lag, window, (cost, live_count, busiest, needed))
    from models import fused_steps  # imports numba: only for the frames that need it

    cells = np.zeros((n_a, C * P), dtype=bool)
    # The NumPy form: every planned sample's position, step by step (the compiled
    # walker; the plan's own floats).
    for j, zyx, rays in () if compiled else fused_steps.plan_positions(plan):
        ra = np.clip(np.floor(zyx[:, a_ax]), 0, n_a - 1).astype(np.int64)
        rb = np.clip(np.floor(zyx[:, b_ax]), 0, n_b - 1).astype(np.int64)
        known = live = None
        if stopped is not None:
            last = stopped[rays]
            live = last >= j  # alive when the slice is processed
            if j >= lag:  # alive when the sequencer read the slab (a superset)
                known = last > j - lag
        cells[:] = False
        if live is None:
            cells[ra, rb] = True
            live_count[j] = ra.size
        else:
            cells[ra[live], rb[live]] = True
            live_count[j] = int(live.sum())
        groups = cells.reshape(n_a, C, P)
        held = groups[:, :, 0].copy()  # clock groups holding a live sample (any of P)
        for p in range(1, P):
            held |= groups[:, :, p]
        cost[j] = held.sum(axis=1)
        lanes = sample_lanes(zyx if live is None else zyx[live], (kp, a_ax, b_ax), shape, P)
        busiest[j] = np.bincount(lanes, minlength=P).max()
        if live is not None:
            cells[ra if known is None else ra[known], rb if known is None else rb[known]] = True
        lo, hi = window(j) if callable(window) else window[j]
        needed[lo : hi + 1] |= mini_blocks_read(cells[:, :n_b])
    stops = 0
    if stopped is not None and plan.ray_ids.size:
        stops = int(np.sum(stopped[plan.ray_ids] < plan.j_hi))
    return BeamSkips(cost, needed, live_count, busiest, stops)


def _compiled_skips(plan, P, stopped, lag, window, out) -> None:
    """:func:`beam_skips`' compiled loop over every sample slice
    (:func:`~models.machines.volumepro.skips_kernel.frame_skips`), filling ``out``:
    ``(cost, live_count, busiest, needed)``."""
    from models import fused_steps  # imports numba: only for the frames that need it
    from models.machines.volumepro.skips_kernel import frame_skips

    kp = plan.principal_axis
    a_ax, b_ax = (ax for ax in range(3) if ax != kp)
    shape = plan.volume.shape
    join, terms = fused_steps.position_terms(plan)  # rays' terms, and the join order
    last = np.zeros(0, dtype=np.int64)
    if stopped is not None:
        last = stopped[plan.ray_ids[join]].astype(np.int64)
    windows = window
    if callable(window):
        windows = np.array([window(j) for j in range(plan.n_steps)], dtype=np.int64)
    rays = _ray_state(join.size)
    frame_skips(
        float(plan.scene.render.supersampling),
        terms,
        join.astype(np.int64),
        plan.j_lo[join].astype(np.int64),
        plan.j_hi[join].astype(np.int64),
        last,
        (int(shape[kp]), int(shape[a_ax]), int(shape[b_ax])),
        P,
        lag,
        windows.reshape(-1, 2),
        rays,
        *out,
        bool(terms.shape[1]) and all(np.all(terms[r] == terms[r, 0]) for r in (0, 1, 3, 5, 7)),
    )
    if rays[0].shape[1] <= _KEEP_RAYS:
        with _rays_lock:
            _rays_kept[:] = [rays]


def _ray_state(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~models.machines.volumepro.skips_kernel.active_rays` for ``n`` rays: a
    finished frame's arrays if they fit (mapped already: fresh ones page-fault on their
    first writes; the loop writes a ray's entries when it joins before reading them), its
    cursor zeroed; else new ones."""
    from models.machines.volumepro.skips_kernel import active_rays  # numba

    with _rays_lock:
        if _rays_kept and _rays_kept[0][0].shape[1] >= n:
            at, ints, cursor = _rays_kept.pop()
            cursor[:] = 0
            return at, ints, cursor
    return active_rays(n)


class Vp1000Transaction(ReadsTheFrame, SlabTransaction):
    """SimPy model of one VolumePro 1000 frame (beam skipping by early ray termination and
    space leaping, rule 6), on the slab machine's event model.

    Parameters
    ----------
    frame : Frame
        Its plan unleaped: the model leaps it when ``[features] space_leaping`` is on, as
        the machine does; its volume and transfer function give the empty space and, when
        ``stopped`` is not set, the functional rung's termination steps.
    **options
        ``groups``, ``pixel_fifo_depth`` (:class:`SlabTransaction`).
    """

    models_skipping = True

    def __init__(self, frame: Frame, **options: Any) -> None:
        self.unleaped = frame
        arch, mode = frame.arch, frame.scene.render.mode
        self.ert_hardware = arch.early_termination and mode in stopping_modes
        leaped = frame
        if arch.space_leaping and mode == "composite":
            leaped = replace(frame, plan=leaping_plan(Backend(frame), frame.plan))
        super().__init__(leaped, **options)

    @property
    def rays_may_stop(self) -> bool:
        """Whether a ray of this scene can stop early on this machine (ERT hardware and an
        opacity threshold below 1, an iso surface, or a stopping depth test)."""
        scene = self.scene
        stopping_geometry = (
            scene.geometry is not None and scene.geometry.depth_test in geometry.STOPPING_TESTS
        )
        stops = scene.render.mode == "iso" or scene.render.early_termination < 1.0
        return self.ert_hardware and (stops or stopping_geometry)

    def run(self) -> TxnTiming:
        """Rule 6's per-beam clocks from the termination steps, then the event model."""
        start = time.perf_counter()
        stopped = self.termination_steps(self.unleaped) if self.rays_may_stop else None
        lag = int(np.ceil(4 * self.scene.render.supersampling))
        self._all_windows(self.plan.n_steps)
        windows = self._window_array(self.plan.n_steps)  # kept for _schedule too
        self.skips = beam_skips(self.plan, self.P, stopped, lag, windows)
        self.skips.leaped = self.unleaped.plan.samples - self.plan.samples
        skips_seconds = time.perf_counter() - start
        timing = super().run()
        timing.counters["transaction.skips_seconds"] = skips_seconds
        timing.counters["transaction.timing_seconds"] += skips_seconds
        return timing
