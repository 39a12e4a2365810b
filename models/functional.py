"""The ``functional`` rung: the bit-exact fixed-point datapath, vectorised over each step.

# Ref: design.md section 3 (functional rung); architectures.md section 9 (units).

It iterates the same :class:`hwsim.golden.SamplePlan` as the golden renderer, so golden
at an architecture's sample positions and functional differ only numerically.  Every
value after voxel conversion is an integer in a named format of ``models.units``; the
only float operations are host-side set-up (LUT, light vectors, correction tables) and
the final 2-D warp, which the VolumePro 500 host also does in floating point.  Samples
come from :class:`TapSource` (a flat voxel array interpolated at each sample's taps); the
rest of the pipeline is :class:`models.backend.Backend`, shared with the cycle rung.

Timing is a closed-form estimate: each slice (or ray step) costs
``ceil(samples / pipelines) + slice_overhead_cycles`` cycles, plus
``section_overhead_cycles`` per section and the pipeline fill latency once.  On a
slice-order machine (every order but ``ray``) ``samples`` is at least the slice's voxel
count: the machine streams the whole slice however few rays the image casts (a machine
that skips beams no ray reaches comes in below the estimate).

The estimate, ``samples`` and ``rays`` count every planned sample; the simulation skips
blocks whose samples provably cannot change the image (:mod:`models.leap`) and processes
each step in parts of :data:`CHUNK` samples.  ``render_functional(..., leap_blocks=False)``
is the reference loop (every planned sample, step by step); both give the same bits.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.golden.positions import SamplePlan, Step
from hwsim.numerics import SATURATIONS
from hwsim.spec.scene import Scene
from models import fused_steps, leap
from models.backend import Backend, RayState, run_compiled
from models.datapath import units_needed
from models.frame import Frame
from models.units import classify as classify_unit
from models.units import combine as combine_unit
from models.units import composite as composite_unit
from models.units import depth as depth_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units import shade as shade_unit

__all__ = ["FunctionalResult", "NEVER", "TapSource", "render_functional", "pipeline_latency"]


def pipeline_latency(scene: Scene, modulates: bool) -> int:
    """Cycles from a voxel read to its sample's composite, for the units the scene uses
    (:func:`models.datapath.units_needed`; ``modulates``: gradient-magnitude opacity),
    plus the LUT combiners and the depth test where the scene uses them."""
    needs = units_needed(scene, modulates)
    timed = {
        "interp": interp_unit,
        "gradient": gradient_unit,
        "classify": classify_unit,
        "shade": shade_unit,
        "composite": composite_unit,
    }
    latency = sum(unit.LATENCY for name, unit in timed.items() if needs[name])
    if scene.classification is not None:
        latency += combine_unit.LATENCY  # the LUT combiners
    if scene.geometry is not None:
        latency += depth_unit.LATENCY  # the depth test against embedded geometry
    return int(latency)


@dataclass
class FunctionalResult:
    """Image (same layout as golden), samples, the cycle estimate and raw counters."""

    image: np.ndarray
    samples: int
    rays: int
    cycles: int
    counters: dict[str, Any] = field(default_factory=dict)
    #: Samples the simulation actually computed (``samples`` minus those skipped as
    #: provably invisible by :mod:`models.leap`); wall-time bookkeeping only.
    simulated: int = 0
    #: Composite and iso: per accumulation ray, the step of its last live sample (early
    #: ray termination, iso hit, a stopping depth test), :data:`NEVER` for rays that never
    #: stopped; None in other modes.  Timing models of machines with ERT hardware read it.
    stopped: np.ndarray | None = None


#: ``FunctionalResult.stopped`` of a ray that never stopped (beyond every step).
NEVER = np.iinfo(np.int64).max // 2


class TapSource:
    """Samples of one step interpolated from flat voxel arrays at each sample's taps
    (computed when first asked for: the compiled composite stage does not need them)."""

    def __init__(self, rung: _Functional, step: Step) -> None:
        self.rung, self.step = rung, step
        self._taps: interp_unit.InterpTaps | None = None

    @property
    def taps(self) -> interp_unit.InterpTaps:
        if self._taps is None:
            self._taps = interp_unit.interp_taps(
                self.step.zyx, self.rung.volume.shape, self.rung.dp.interp
            )
        return self._taps

    def _interpolate(self, promoted: np.ndarray, taps: interp_unit.InterpTaps) -> np.ndarray:
        return interp_unit.interpolate(promoted, taps, self.rung.dp.interp, promoted=True)

    def value(self) -> np.ndarray:
        return self._interpolate(self.rung.flat, self.taps)

    def channels(self) -> list[np.ndarray]:
        return [self._interpolate(c, self.taps) for c in self.rung.pre]

    def composite_fused(self, step: Step, factor: np.ndarray | None, state: RayState) -> bool:
        """Run the back end's composite stage on ``step`` in one compiled pass
        (:mod:`models.fused`) when the frame allows it; False: use the unit chain."""
        return run_compiled(self.rung.kernel, step, factor, state)

    def gradient(self, sel: np.ndarray) -> np.ndarray:
        rung, t = self.rung, self.taps
        if rung.diffs is not None:
            ts = t.subset(sel)
            return np.stack([self._interpolate(d, ts) for d in rung.diffs], axis=1)
        # np.take: row and column gathers, much faster than 2-D fancy indexing.
        return gradient_unit.sample_differences(
            rung.flat,
            np.take(self.step.zyx, sel, axis=0),
            rung.volume.shape,
            rung.dp.interp,
            promoted=True,
            center=(np.take(t.cells, sel, axis=1), np.take(t.frac, sel, axis=1)),
        )


class _Functional:
    def __init__(
        self, backend: Backend, *, leap_blocks: bool = True, compiled: bool = True
    ) -> None:
        self.backend = be = backend
        self.leap = leap_blocks
        self.volume, self.dp, self.plan, self.arch = be.volume, be.dp, be.plan, be.arch
        self.pre = None
        if be.pre_classified:
            cfg = be.dp.interp
            self.pre = [interp_unit.promote(c.ravel(), cfg) for c in be.classified_voxels(be.raw)]
        self._flat: np.ndarray | None = None
        self._diffs: list[np.ndarray] | None = None
        self._voxel_diffs = be.need_grad and be.dp.gradient.source == "voxel"
        self.kernel = None
        if compiled:
            from models import fused  # imports numba: only when a frame may use it

            if fused.eligible(be):
                self.kernel = fused.CompositeKernel(be, self._voxel_diffs)

    # Every array the unit chain's interpolator reads, promoted once per frame (int32 when
    # exact), when first needed: a frame that the compiled kernel runs reads none of them.

    @property
    def flat(self) -> np.ndarray:
        if self._flat is None:
            self._flat = interp_unit.promote(self.backend.raw.ravel(), self.dp.interp)
        return self._flat

    @property
    def diffs(self) -> list[np.ndarray] | None:
        if self._voxel_diffs and self._diffs is None:
            self._diffs = [
                interp_unit.promote(d, self.dp.interp)
                for d in gradient_unit.voxel_differences(self.backend.raw)
            ]
        return self._diffs

    def run(self, progress: Callable[[int, int], None] | None) -> FunctionalResult:
        plan, be = self.plan, self.backend
        state = be.new_state(plan.n_rays)
        before = SATURATIONS.copy()
        P = self.arch.pipelines
        # Closed form over every planned sample: the machine visits them all.  A
        # slice-order machine also streams every voxel of the slice whatever the image
        # (a small image does not shorten a slice), so a step costs at least that.
        per_step = leap.step_sample_counts(plan)
        if plan.kind != "ray" and plan.principal_axis is not None:
            shape = be.volume.shape
            per_step = np.maximum(per_step, int(np.prod(shape)) // shape[plan.principal_axis])
        cycles = int(np.sum(-(-per_step // P))) + plan.n_steps * self.arch.slice_overhead_cycles
        blocks = leap.invisible_blocks(be) if self.leap else None
        stops = be.mode in ("composite", "iso")
        stopped = np.full(state.alive.shape, NEVER, dtype=np.int64)
        if blocks is None:
            for j, step in enumerate(plan.steps()):
                for part in _chunks(step) if self.leap else [step]:
                    be.process(part, self._source, state)
                if stops and step.rays.size:  # rays that stopped at this step
                    rays = step.rays
                    stopped[rays[~state.alive[rays] & (stopped[rays] == NEVER)]] = j
                if progress is not None:
                    progress(j + 1, plan.n_steps)
            simulated = state.samples
        elif fused_steps.applies(be, plan, self.kernel, blocks):
            simulated = fused_steps.run_steps_compiled(
                plan, blocks, self.kernel, state, stopped, progress
            )
            leap.visits(plan, be, stopped, state)
        else:
            simulated = self._run_leapt(leap.leapt_plan(plan, blocks), state, progress, stopped)
        sections = 0
        if self.arch.section_width and plan.shape[1] > 0:
            sections = -(-plan.shape[1] // self.arch.section_width)
        latency = pipeline_latency(be.scene, be.transfer.modulates)
        cycles += sections * self.arch.section_overhead_cycles + latency
        image = be.finish(state.acc, state.touched, state.dt_sum)
        clipped = {k: v - before.get(k, 0) for k, v in SATURATIONS.items() if v - before.get(k, 0)}
        counters = {
            "functional.samples": state.samples,
            "functional.sections": sections,
            "functional.saturated": clipped,
        }
        return FunctionalResult(
            image,
            state.samples,
            int(state.touched.sum()),
            int(cycles),
            counters,
            simulated,
            stopped if stops else None,
        )

    def _run_leapt(
        self,
        sim: SamplePlan,
        state: RayState,
        progress: Callable[[int, int], None] | None,
        stopped: np.ndarray,
    ) -> int:
        """Simulate only the samples of ``sim`` (the plan minus invisible blocks), then
        recount what the machine visits in the full plan; returns the samples simulated
        and fills ``stopped`` (:attr:`FunctionalResult.stopped`)."""
        be = self.backend
        stops = be.ert < 1.0 or be.mode == "iso"
        for j, step in enumerate(sim.steps(state.alive)):
            for part in _chunks(step):
                be.process(part, self._source, state)
            if stops and step.rays.size:
                rays = step.rays
                stopped[rays[~state.alive[rays]]] = j
            if progress is not None:
                progress(j + 1, sim.n_steps)
        simulated = state.samples
        leap.visits(self.plan, be, stopped, state)
        return simulated

    def _source(self, step: Step) -> TapSource:
        return TapSource(self, step)


#: Samples per back-end call: a step's rays are independent (each at most once per step),
#: so a step may be processed in parts.  Measured on the bench scene (2 MiB L2): smaller
#: parts pay NumPy's per-call overhead, larger ones spill the temporaries out of cache.
CHUNK = 16384


def _chunks(step: Step) -> list[Step]:
    """``step`` cut into consecutive parts of at most :data:`CHUNK` samples."""
    n = step.rays.size
    if n <= CHUNK:
        return [step]
    per_ray_dt, per_ray_view = not np.isscalar(step.dt), step.view is not None
    per_ray_view = per_ray_view and step.view.ndim == 2
    return [
        Step(
            step.rays[s : s + CHUNK],
            step.zyx[s : s + CHUNK],
            step.dt[s : s + CHUNK] if per_ray_dt else step.dt,
            step.view[s : s + CHUNK] if per_ray_view else step.view,
        )
        for s in range(0, n, CHUNK)
    ]


def render_functional(
    frame: Frame,
    *,
    progress: Callable[[int, int], None] | None = None,
    leap_blocks: bool = True,
    compiled: bool = True,
) -> FunctionalResult:
    """Render ``frame`` with the fixed-point units of its architecture at its plan's
    sample positions.

    ``leap_blocks`` lets the simulation skip blocks whose samples provably cannot change
    the image (:mod:`models.leap`); image, samples, rays, cycles and saturation counts
    are the same either way, only the wall time differs.  ``compiled`` runs the composite
    stage, where the frame allows it, as one compiled pass per step part
    (:mod:`models.fused`) instead of the chain of vectorised unit calls; again the same
    bits either way.
    """
    backend = Backend(frame)
    return _Functional(backend, leap_blocks=leap_blocks, compiled=compiled).run(progress)
