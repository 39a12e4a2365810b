"""The pipeline back end every bit-exact rung shares: set-up, per-sample stages, finishing.

# Ref: design.md section 3 (one description of the hardware, many rungs);
#      architectures.md section 9.1 (classifier, gradient, shader, compositor units).

A rung differs from another in *where its samples come from*: the ``functional`` rung
interpolates a flat voxel array at each sample's taps, the ``cycle`` rung reads the
voxels out of its modelled memory modules, ring links and delay FIFOs.  Both hand a
:class:`SampleSource` for each step's samples to :meth:`Backend.process`, which runs the
rest of the pipeline (classification, gradient-magnitude modulation, shading, opacity
correction, compositing, crop and cut masks) with the units of ``models.units`` -- one
copy of that arithmetic for every rung.

Host-side set-up (classification LUT, pre-classified voxels, gradient-magnitude table,
shader reflectance set-up) and the host-side finish (output format to float, the 2-D
warp of a base-plane image) live here too.
"""

from __future__ import annotations

import functools
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from hwsim.core.errors import InputError
from hwsim.golden import geometry, occupancy
from hwsim.golden.camera import index_to_world
from hwsim.golden.positions import Step
from hwsim.golden.steps import all_alive
from hwsim.spec.scene_features import VALUE_FIELD, check_machine
from models.datapath import units_needed
from models.frame import Frame
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import crop as crop_unit
from models.units import depth as depth_unit
from models.units import gradient as gradient_unit
from models.units import shade as shade_unit
from models.units.cursor import CursorTable
from models.units.multilut import MultiLut
from models.units.voxel import convert_values, converted_volume

__all__ = ["Backend", "RayState", "SampleSource", "run_compiled", "subset_step", "ONE"]

ONE = 1 << 12  # 1.0 in UQ1.12


class SampleSource(Protocol):
    """Interpolated samples of one step, however a rung obtains them.

    ``value()`` is the raw sample of every step sample (``in_frac_bits = 0`` plus
    ``S = interp.sample_frac_bits`` fraction bits); ``channels()`` the four interpolated
    pre-classified channels (RGBA, S fraction bits); ``gradient(sel)`` the raw central
    differences ``(len(sel), 3)`` in ``(x, y, z)`` of the samples ``sel`` (index array),
    before :func:`~models.units.gradient.to_world`.
    """

    def value(self) -> np.ndarray: ...

    def channels(self) -> list[np.ndarray]: ...

    def gradient(self, sel: np.ndarray) -> np.ndarray: ...


@dataclass
class RayState:
    """Per-ray accumulators of one frame (the compositing buffers' contents)."""

    acc: np.ndarray
    alive: np.ndarray
    touched: np.ndarray
    dt_sum: np.ndarray | None = None
    samples: int = 0
    extra: dict = field(default_factory=dict)


def run_compiled(kernel, step: Step, factor: np.ndarray | None, state, *source) -> bool:
    """A source's ``composite_fused``: run the back end's composite stage on ``step`` with
    the compiled ``kernel`` (``kernel.run(*source, step, factor, state, table)``) when the
    frame allows it (a kernel with a table for ``step.dt``); False: use the unit chain."""
    table = None if kernel is None else kernel.table(step.dt)
    if table is None:
        return False
    kernel.run(*source, step, factor, state, table)
    return True


def subset_step(step: Step, keep: np.ndarray) -> Step:
    """The samples of ``step`` where ``keep`` is True (the same step when all are)."""
    if keep.all():
        return step
    dt = step.dt if np.isscalar(step.dt) else step.dt[keep]
    # np.compress: the same rows as boolean indexing, several times faster for (n, 3).
    return Step(step.rays[keep], np.compress(keep, step.zyx, axis=0), dt)


#: Per volume, voxel width and block size: the blocks' raw value ranges (of the voxels
#: ``converted_volume`` keeps per volume), so later frames do not rescan it for leaping.
_RANGES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class Backend:
    """Set-up and per-sample stages of one scene on one datapath."""

    def __init__(
        self, frame: Frame, *, exercise_unused: bool = False, compiled: bool = True
    ) -> None:
        self.frame = frame
        self.exercise_unused = exercise_unused
        #: Whether a machine may run the composite stage in a compiled kernel where it
        #: has one (False: always the unit chain, to compare the two).
        self.compiled = compiled
        scene, volume, transfer, plan = frame.scene, frame.volume, frame.transfer, frame.plan
        self.scene, self.volume, self.transfer, self.plan = scene, volume, transfer, plan
        self.arch = frame.arch
        self.dp = dp = frame.datapath
        self.mode = scene.render.mode
        # The raw-value map (the volume's conversion rule); the converted voxels
        # themselves (:attr:`raw`) only when a rung reads the whole volume.
        self.vmap = convert_values(np.array(volume.value_range), volume, dp.voxel_bits)[1]
        self.S = dp.interp.sample_frac_bits
        self.ref = min(volume.spacing)
        composite = self.mode == "composite"
        self.need_grad = units_needed(scene, transfer.modulates)["gradient"]
        if composite or self.mode == "iso" or exercise_unused:
            self.lut = classify_unit.build_lut(
                transfer, self.vmap.to_value, dp.voxel_bits, dp.classify
            )
        self.pre_classified = composite and transfer.order == "pre"
        #: VolumePro 500's 3-D cursor, drawn over the samples on it (composite only).
        self.cursor = CursorTable(scene.cursor) if scene.cursor is not None else None
        #: A supervolume brick's plan (hwsim.golden.bricks): crop, cut planes and the
        #: cursor are placed in the whole volume, so its positions move back there.
        self.origin = getattr(plan, "origin", None)
        self.scene_volume = plan.whole.volume if self.origin is not None else volume
        self.illum_table = None
        if self.need_grad and (transfer.modulates or transfer.modulates_illumination):
            # Largest |gradient| the data can have, in value units per world unit.
            # The converted value range (conversion is monotone: the raw extremes of the
            # whole volume; a brick of a supervolume shares them).
            raw_lo, raw_hi = convert_values(np.array(volume.value_range), volume, dp.voxel_bits)[0]
            span = float(raw_hi - raw_lo) * self.vmap.scale
            self.gm_max = np.sqrt(3.0) * span / self.ref
            self.gm_table = classify_unit.build_gm_table(transfer, self.gm_max, dp.classify)
            if transfer.modulates_illumination and scene.lit:
                self.illum_table = classify_unit.build_gm_table(
                    transfer, self.gm_max, dp.classify, illumination=True
                )
            # An integer magnitude m stands for m * scale / (2 * 2**S * min spacing).
            per_unit = self.vmap.scale / (2.0 * (1 << self.S) * self.ref)
            self.gm_scale = classify_unit.gm_scale(per_unit, self.gm_max, dp.classify)
        if scene.lit or exercise_unused:
            from hwsim.spec.scene import Light

            lights = [
                (plan.camera.light_to_world(light.direction, light.space), light.intensity)
                for light in (scene.lights or (Light(),))
            ]
            m = scene.material
            material = (m.ambient, m.diffuse, m.specular, m.shininess)
            view = plan.camera.toward_viewer
            self.shader = None
            if view.ndim == 1 or plan.kind == "shear-warp":
                self.shader = shade_unit.setup(lights, -plan.camera.d, material, dp.shade)
            else:
                self.lights, self.material = lights, material
        self.iso_rgb = np.round(np.asarray(scene.render.iso_color) * ONE).astype(np.int64)
        lo, hi = volume.value_range
        iso = scene.render.iso_value
        iso = 0.5 * (lo + hi) if iso is None else iso
        self.iso_raw = int(np.ceil((iso - self.vmap.offset) / self.vmap.scale * (1 << self.S)))
        self.ert = scene.render.early_termination
        self.multilut: MultiLut | None = None
        self.depth: depth_unit.DepthBuffers | None = None
        self.stopped: np.ndarray | None = None  # rays the depth test ended this step
        if scene.classification is not None or scene.geometry is not None:
            self._setup_features()

    @functools.cached_property
    def raw(self) -> np.ndarray:
        """The whole volume as raw voxels (:func:`~models.units.voxel.converted_volume`),
        converted on first use: a frame split across workers reads its voxels a part at
        a time instead (:mod:`hwsim.volumes.parts`) and never asks for this."""
        return converted_volume(self.volume, self.dp.voxel_bits)[0]

    def classified_voxels(self, raw: np.ndarray) -> list[np.ndarray]:
        """Pre-classification: the LUT applied to raw voxels (any shape), RGBA UQ1.12."""
        if self.multilut is not None:
            inputs = {VALUE_FIELD: np.asarray(raw, dtype=np.int64).ravel()}
            rgb, alpha = self.multilut.classify({**inputs, **self.multilut.field_raw(raw)}, 0)
            return [rgb[:, 0], rgb[:, 1], rgb[:, 2], alpha]
        return classify_unit.classify_voxels(raw, self.lut, self.dp.voxel_bits, self.dp.classify)

    # ------------------------------------------------------------------ state

    def new_state(self, n_rays: int) -> RayState:
        """Cleared accumulators for ``n_rays`` rays (each mode's identity element)."""
        mode = self.mode
        dt_sum = None
        if mode in ("composite", "iso"):
            acc = np.zeros((n_rays, 4), dtype=np.int64)
        elif mode == "mip":
            acc = np.full(n_rays, -1, dtype=np.int64)
        elif mode == "minip":
            acc = np.full(n_rays, np.iinfo(np.int64).max, dtype=np.int64)
        else:
            acc = np.zeros(n_rays, dtype=np.int64)
            dt_sum = np.zeros(n_rays, dtype=np.int64)
        return RayState(
            acc=acc,
            alive=np.ones(n_rays, dtype=bool),
            touched=np.zeros(n_rays, dtype=bool),
            dt_sum=dt_sum,
        )

    def cleared_acc(self, rays: np.ndarray, state: RayState) -> None:
        """Reset the accumulators of ``rays`` to the mode's identity (a lost hand-off)."""
        fresh = self.new_state(1)
        state.acc[rays] = fresh.acc[0]
        if state.dt_sum is not None:
            state.dt_sum[rays] = 0

    # ------------------------------------------------------------------ per step

    def scene_positions(self, step: Step) -> np.ndarray:
        """The step's positions in the scene's volume (a brick's, moved back)."""
        return step.zyx if self.origin is None else step.zyx + self.origin

    def masks(self, step: Step) -> tuple[Step, np.ndarray | None]:
        """Crop box and cut planes: the samples kept and their cut-plane factors."""
        keep, factor = None, None
        zyx = self.scene_positions(step)
        if self.scene.crop is not None:
            keep = crop_unit.crop_keep(zyx, self.scene.crop)
        if self.scene.cut_planes:
            factor = crop_unit.cut_factor(
                index_to_world(zyx, self.scene_volume),
                self.scene.cut_planes,
                # The machine's plane count; a what-if beyond it (hwsim.spec.machine_features)
                # gets a unit as wide as the scene asks.
                crop_unit.CutConfig(
                    max_planes=max(1, self.arch.cut_planes, len(self.scene.cut_planes))
                ),
            )
            keep = factor > 0 if keep is None else keep & (factor > 0)
        if self.depth is not None:
            passed = self._depth_test(step)
            stopping = self.scene.geometry.depth_test in geometry.STOPPING_TESTS  # type: ignore[union-attr]
            if stopping and not self.plan.back_to_front:  # a far-first ray meets it last
                self.stopped = step.rays[~passed]
            keep = passed if keep is None else keep & passed
        if keep is not None and self.cursor is not None and self.cursor.cursor.disable_crop:
            keep |= self.cursor.parts(zyx) >= 0  # drawn where the volume is cut away
        if keep is not None:
            step = subset_step(step, keep)
            factor = factor[keep] if factor is not None else None
        return step, factor

    def process(
        self, step: Step, make_source: Callable[[Step], SampleSource], state: RayState
    ) -> Step:
        """Run one step's samples through the back end; returns the samples processed."""
        mode, dp = self.mode, self.dp
        if mode in ("composite", "iso") and not all_alive(state.alive, step.rays):
            step = subset_step(step, state.alive[step.rays])
        step, factor = self.masks(step)
        if self.stopped is not None:  # embedded geometry ends these rays
            state.alive[self.stopped] = False
            self.stopped = None
        if not step.rays.size:
            return step
        state.samples += step.rays.size
        state.touched[step.rays] = True
        src = make_source(step)
        if self.exercise_unused:
            self._exercise(step, src, state)
        acc = state.acc
        if mode == "composite":
            self._composite(step, src, factor, state)
        elif mode == "iso":
            s = src.value()
            hit = composite_unit.iso_hit(s, self.iso_raw)
            if hit.any():
                rays = step.rays[hit]
                rgb = np.broadcast_to(self.iso_rgb, (rays.size, 3))
                if self.scene.lit:
                    g = self._to_world(src.gradient(np.flatnonzero(hit)))
                    rgb = self._shade(rgb, g, rays)
                acc[rays, :3] = rgb.astype(np.int64) << (dp.composite.acc_frac_bits - 12)
                acc[rays, 3] = 1 << dp.composite.acc_frac_bits
                state.alive[rays] = False
        else:
            s = src.value()
            if mode == "mip":
                composite_unit.mip(acc, step.rays, s)
            elif mode == "minip":
                composite_unit.minip(acc, step.rays, s)
            else:
                if factor is not None:
                    s = (s * factor + (1 << 11)) >> 12
                composite_unit.xray(acc, step.rays, s, step.dt, dp.composite)
                composite_unit.xray(
                    state.dt_sum, step.rays, np.full(s.size, 1, np.int64), step.dt, dp.composite
                )
        return step

    def _exercise(self, step: Step, src: SampleSource, state: RayState) -> None:
        """Run the units this scene does not use on every sample and discard the results:
        what a fixed pipeline with disabled units does (the elision check)."""
        s = src.value()
        rgb, _ = classify_unit.classify(s, self.lut, self.dp.voxel_bits, self.S, self.dp.classify)
        if not self.scene.lit:
            g = self._to_world(src.gradient(np.arange(s.size)))
            self._shade(rgb, g, step.rays)
        state.extra["exercised"] = state.extra.get("exercised", 0) + s.size

    def _to_world(self, g: np.ndarray) -> np.ndarray:
        return gradient_unit.to_world(g, self.volume.spacing, self.S, self.dp.gradient)

    def _shade(self, rgb: np.ndarray, g: np.ndarray, rays: np.ndarray, illum=None) -> np.ndarray:
        normals = gradient_unit.normals(g, self.dp.gradient)
        shader = self.shader
        if shader is None:
            shader = shade_unit.setup(
                self.lights, self.plan.toward_viewer(rays), self.material, self.dp.shade
            )
        return shade_unit.shade(shader, rgb, normals, illum)

    def occupied_blocks(self, block: int = occupancy.BLOCK) -> np.ndarray | None:
        """Blocks of ``block^3`` voxels that can give a visible sample, for space leaping:
        those whose voxel range (with the ``+1`` neighbours) reaches an entry of *this*
        datapath's LUT with non-zero opacity (lerps are convex, so a sample lies in the
        range and its entry between the range's entries), or, for iso, the iso value.
        ``None`` where leaping does not apply (MIP, MinIP and X-ray see every sample).
        One rule for the cycle and transaction models of every machine that leaps."""
        if self.mode not in ("composite", "iso"):
            return None
        kept = _RANGES.setdefault(self.volume, {})
        key = (self.dp.voxel_bits, block)
        if key not in kept:
            kept[key] = tuple(x.astype(np.int64) for x in occupancy.block_ranges(self.raw, block))
        lo, hi = kept[key]
        if self.mode == "iso":
            return (hi << self.S) >= self.iso_raw
        dp = self.dp
        first, last = (
            classify_unit.lut_index(v << self.S, dp.voxel_bits, self.S, dp.classify)
            for v in (lo, hi)
        )
        return self.transparent_ranges()[first] <= last

    def transparent_ranges(self) -> np.ndarray:
        """``next_visible[i]``: the first LUT entry ``>= i`` with non-zero opacity (the
        table size when none).  A sample whose entry range ``[lo, hi]`` has
        ``next_visible[lo] > hi`` is transparent, whatever it interpolates to."""
        alpha = self.lut.alpha12
        entries = alpha.size
        if self.multilut is not None:  # combined opacity: no bound from one LUT
            return np.arange(entries)
        idx = np.where(alpha > 0, np.arange(entries), entries)
        return np.minimum.accumulate(idx[::-1])[::-1]

    def _composite(self, step: Step, src: SampleSource, factor, state: RayState) -> None:
        dp = self.dp
        part = self.cursor.parts(self.scene_positions(step)) if self.cursor is not None else None
        maybe = getattr(src, "maybe_visible", None)
        if maybe is not None:
            # The source knows samples that are provably transparent (all their voxels
            # classify to opacity 0): skip simulating them, they change nothing (unless
            # the cursor is drawn over them).
            keep = maybe()
            if keep is not None and part is not None:
                keep = keep | (part >= 0)
            if keep is not None and not keep.all():
                sel = np.flatnonzero(keep)
                state.extra["skipped"] = state.extra.get("skipped", 0) + step.rays.size - sel.size
                if not sel.size:
                    return  # every sample skipped (counted above: a step of only those too)
                step = subset_step(step, keep)
                factor = factor[sel] if factor is not None else None
                part = part[sel] if part is not None else None
                src = src.subset(sel)
        fused = getattr(src, "composite_fused", None)
        if fused is not None and fused(step, factor, state):
            return  # the source ran this whole stage in one compiled pass (models.fused)
        if self.pre_classified:
            chans = src.channels()
            alpha = (chans[3] + (1 << (self.S - 1))) >> self.S
        else:
            s = src.value()
            if self.multilut is not None:
                rgb, alpha = self._classify_multi(s, step)
            else:
                rgb, alpha = classify_unit.classify(s, self.lut, dp.voxel_bits, self.S, dp.classify)
        if factor is not None:
            alpha = classify_unit.scale_alpha_raw(alpha, factor)
        vis = alpha > 0 if part is None else (alpha > 0) | (part >= 0)
        if not vis.any():
            return
        sel = np.flatnonzero(vis)
        rays, alpha = step.rays[sel], alpha[sel]
        if self.pre_classified:
            rgb = np.stack([(c[sel] + (1 << (self.S - 1))) >> self.S for c in chans[:3]], axis=1)
        else:
            rgb = np.take(rgb, sel, axis=0)
        if self.need_grad:
            g = self._to_world(src.gradient(sel))
            index = illum = None
            if self.transfer.modulates or self.illum_table is not None:
                index = classify_unit.gm_index(
                    gradient_unit.magnitude(g), self.gm_scale, dp.classify
                )
            if self.transfer.modulates:
                alpha = classify_unit.modulate(alpha, index, self.gm_table)
            if self.illum_table is not None:
                illum = self.illum_table[index]
            if self.scene.lit:
                rgb = self._shade(rgb, g, rays, illum)
        if part is not None:
            rgb, alpha = self.cursor.blend(rgb, alpha, part[sel])  # type: ignore[union-attr]
        dt = step.dt if np.isscalar(step.dt) else step.dt[sel]
        alpha = composite_unit.correct_opacity(alpha, np.asarray(dt) / self.ref, dp.composite)
        if self.plan.back_to_front:  # scene.py refuses early termination with it
            composite_unit.back_to_front(state.acc, rays, rgb, alpha, dp.composite)
            return
        composite_unit.front_to_back(state.acc, rays, rgb, alpha, dp.composite)
        if self.ert < 1.0:
            state.alive[rays] = ~composite_unit.terminated(state.acc[rays], self.ert, dp.composite)

    # ----------------------------------- multi-LUT classification, embedded geometry

    def _setup_features(self) -> None:
        """Multi-LUT classification and embedded geometry: refused on machines without
        them (``[features] classification_luts``, ``embedded_geometry``)."""
        scene, arch, dp = self.scene, self.arch, self.dp
        check_machine(scene, arch)
        if scene.classification is not None:
            self.multilut = MultiLut(
                scene, self.volume, dp.voxel_bits, self.vmap.to_value, dp.classify
            )
            self.field_flat = self.multilut.field_raw(self.raw)
        if scene.geometry is not None:
            if self.plan.kind not in ("ray", "shear-image"):
                raise InputError(
                    "embedded geometry needs rays through image pixels",
                    source=arch.source,
                    key="pipeline.order",
                    allowed="shear-image",
                )
            buffers = geometry.rasterise(
                scene.geometry, self.plan.camera, scene.view.distance, scene.base_dir
            )
            self.depth = depth_unit.DepthBuffers(buffers)

    def _depth_test(self, step: Step) -> np.ndarray:
        """Samples passing the depth test against their pixel's ``depth.z``."""
        d = geometry.sample_depth(step.zyx, self.plan.camera, self.volume, self.scene.view.distance)
        test = self.scene.geometry.depth_test  # type: ignore[union-attr]
        return depth_unit.passes(test, depth_unit.quantise_depth(d), self.depth.z[step.rays])  # type: ignore[union-attr]

    def _classify_multi(self, s: np.ndarray, step: Step) -> tuple[np.ndarray, np.ndarray]:
        """Post-classification through the multi-LUT classifier; declared fields are
        interpolated from their own arrays at the step's positions."""
        ml = self.multilut
        fields = ml.interpolate_fields(  # type: ignore[union-attr]
            self.field_flat, step.zyx, self.volume.shape, self.dp.interp
        )
        return ml.classify({VALUE_FIELD: s, **fields}, self.S)  # type: ignore[union-attr]

    # ------------------------------------------------------------------ host side

    def finish(self, acc: np.ndarray, touched: np.ndarray, dt_sum) -> np.ndarray:
        """Host side: accumulators to the final float image (output format, then warp)."""
        mode, plan, vmap = self.mode, self.plan, self.vmap
        lo, hi = self.volume.value_range
        if mode in ("composite", "iso"):
            if self.depth is not None:
                depth_unit.blend(acc, self.depth, self.dp.composite)
            out = composite_unit.to_output(acc, self.dp.composite)
            return plan.to_image(composite_unit.output_to_float(out, self.dp.composite), 0.0)
        if mode in ("mip", "minip"):
            values = vmap.offset + vmap.scale * acc.astype(np.float64) / (1 << self.S)
            values[~touched] = lo if mode == "mip" else hi
            return plan.to_image(values, lo if mode == "mip" else hi)
        scale = 1.0 / ((1 << self.S) * (1 << self.dp.composite.xray_frac_bits))
        dts = dt_sum.astype(np.float64) / (1 << self.dp.composite.xray_frac_bits)
        values = vmap.offset * dts + vmap.scale * acc.astype(np.float64) * scale
        return plan.to_image(values, 0.0)
