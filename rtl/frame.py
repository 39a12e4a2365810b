"""Host side of the RTL top: what the host writes before a frame and how it reads the
image back.

# Ref: architectures.md section 1 (Cube-4: the host loads the volume and the per-slice
#      constants of a parallel projection); docs/cycle.md (the machine reproduced).

The host writes what a driver would: the volume (into the voxel memory outside the chip,
:attr:`FrameProgram.volume_words`), the tables (LUT, opacity correction,
gradient-magnitude table, the shader's specular table or, for a reflectance-map shader
(VolumePro 500), its diffuse and specular maps computed from the lights as the VLI driver
does, the geometry unit's per-slice constants and ray bounds) and the frame's geometry
and shading registers.  No timing value of any model (latency, slice period, stall
counts) is written: the top's cycles are its own.

:func:`prepare` turns a scene, its sample plan and an architecture into a
:class:`FrameProgram`: load words (volume in the skewed layout, classification LUT,
opacity-correction table, ray table, per-slice constants) and frame registers.  It
refuses, naming the key, what the top does not model.  :func:`decode` assembles the
image from the pixels the bus delivered, exactly as the cycle rung's host does.

The per-slice constants are found by reading the plan (the geometry unit's output) and
are then *checked* against it: every sample the hardware will take (one per slot, the
sample whose nearest voxel is the slot's voxel) must be exactly the plan's samples of
that step, with the same cells and quantised weights.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.golden.positions import SamplePlan
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import Scene
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes.volume import Volume
from models.backend import Backend
from models.datapath import Datapath
from models.frame import Frame
from models.machines.common.results import UNITS, CycleResult, elaborate_units
from models.machines.cube4.frame import Cube4Frame
from models.units import composite as composite_unit
from models.units import skew
from rtl.top import RMW_WINDOW
from rtl.top_layouts import (
    LOAD_CORRECTION,
    LOAD_DIFFUSE_MAP,
    LOAD_GM,
    LOAD_LUT,
    LOAD_RAYS,
    LOAD_SLICES,
    LOAD_SPEC,
    TopGeometry,
    load_layout,
    ray_layout,
    slice_layout,
)
from rtl.top_pipeline import MAX_LIGHTS

#: Processing orders the RTL top implements (the Cube-4 family).
RTL_ORDERS = ("slice-parallel",)

__all__ = ["FrameProgram", "prepare", "decode", "MAX_AXIS", "RTL_ORDERS", "size_class"]

#: Largest volume (voxels per axis) the RTL top renders.
MAX_AXIS = 128
#: The top is built for the smallest of these that holds the frame's volume (one build
#: per size class and configuration, cached).
SIZE_CLASSES = (16, 32, 64, 128)


def size_class(shape: tuple[int, ...]) -> int:
    """The top's ``max_axis`` for a volume of ``shape``."""
    return next(n for n in SIZE_CLASSES if n >= max(shape))


@dataclass
class FrameProgram:
    """Everything the host writes for one frame, and what it needs to read it back."""

    geo: TopGeometry
    backend: Backend
    loads: list[tuple[int, int, int]]
    registers: dict[str, int]
    volume_words: list[int] = field(default_factory=list)
    elaborated: list[str] = field(default_factory=list)

    @property
    def dp(self) -> Datapath:
        return self.backend.dp

    @property
    def plan(self) -> SamplePlan:
        return self.backend.plan

    @property
    def n_rays(self) -> int:
        """Base-plane rays, used or not (the ray table's rows)."""
        return self.plan.shape[0] * self.plan.shape[1]

    @property
    def elided(self) -> list[str]:
        return [u for u in UNITS if u not in self.elaborated]

    def load_words(self) -> np.ndarray:
        """The loads packed as :func:`rtl.top_layouts.load_layout` words (Python ints)."""
        lay = load_layout(self.geo, self.dp)
        t_off = lay["target"].offset
        a_off = lay["addr"].offset
        d_off = lay["data"].offset
        return [(t << t_off) | (a << a_off) | (d << d_off) for t, a, d in self.loads]


def _refuse(message: str, key: str, allowed: str, source=None) -> InputError:
    return InputError(message, source=source, key=key, allowed=allowed)


def _pack(layout, fields: dict[str, int]) -> int:
    word = 0
    for name, value in fields.items():
        f = layout[name]
        width = f.shape.width
        word |= (int(value) & ((1 << width) - 1)) << f.offset
    return word


def _check_scene(
    scene: Scene, volume: Volume, transfer: TransferFunction, arch: ArchConfig, dp: Datapath
):
    if arch.order not in RTL_ORDERS:
        raise NotAvailableError(
            f"the rtl rung builds the Cube-4 and vg500 tops; {arch.name} ({arch.order} order) "
            "has no RTL top",
            key="--arch",
            allowed="cube4, cube4-teramac, volumepro500 (unlit composite or mip) or a "
            "slice-parallel FILE.toml",
        )
    if scene.view.projection != "parallel":
        raise _refuse(
            "the RTL top renders parallel views (per-slice constants); perspective is "
            "modelled at the cycle rung only",
            "view.projection",
            "parallel",
            scene.source if hasattr(scene, "source") else None,
        )
    if max(volume.shape) > MAX_AXIS:
        raise _refuse(
            f"volume {volume.shape[::-1]} is too big for the RTL top",
            "volume",
            f"at most {MAX_AXIS} voxels per axis",
        )
    if min(volume.shape) < 4:
        raise _refuse(
            f"volume {volume.shape[::-1]} is too small for the RTL top", "volume", ">= 4 per axis"
        )
    mode = scene.render.mode
    if mode not in ("composite", "mip"):
        raise _refuse(f"mode {mode!r} is not in the RTL top", "render.mode", "composite, mip")
    if scene.lit and dp.shade.method == "phong" and len(scene.lights) > MAX_LIGHTS:
        raise _refuse(
            f"{len(scene.lights)} lights; the RTL top's shader sums {MAX_LIGHTS}",
            "lights",
            f"at most {MAX_LIGHTS} lights",
        )
    if mode == "composite" and transfer.order == "pre":
        raise _refuse("the RTL top post-classifies", "transfer.order", "post")
    if scene.cursor is not None:
        raise _refuse("the RTL top has no cursor unit", "cursor", "no [cursor]")
    if scene.render.blend_order != "front-to-back":
        raise _refuse(
            "the RTL top's compositor blends front to back", "render.blend_order", "front-to-back"
        )
    if scene.cut_planes:
        raise _refuse("the RTL top's crop unit has no cut planes", "cut_planes", "none")
    if mode == "composite" and scene.lit and transfer.modulates_illumination:
        raise _refuse(
            "the RTL top's shader has no gradient-magnitude illumination modulation",
            "transfer.gradient_illumination",
            "none (gradient_opacity is modelled)",
        )


def prepare(frame: Frame, *, max_axis: int | None = None) -> FrameProgram:
    """The loads and registers of ``frame`` on the RTL top of its architecture.

    Raises
    ------
    InputError
        What the top does not model (key named): non-Cube-4 machines, perspective,
        volumes above ``max_axis`` voxels per axis, modes other than composite and MIP,
        pre-classification, cut planes, more than ``MAX_LIGHTS`` lights on the Phong shader,
        gradient-magnitude illumination modulation, per-ray weights within a slice.

    ``max_axis``: the top's size (default: the smallest of :data:`SIZE_CLASSES` that holds
    the volume).
    """
    scene, volume, transfer = frame.scene, frame.volume, frame.transfer
    arch, plan, dp = frame.arch, frame.plan, frame.datapath
    _check_scene(scene, volume, transfer, arch, dp)
    backend = Backend(frame)
    machine = Cube4Frame(backend)  # the machine's refusals and frame geometry
    P = machine.P
    geo = TopGeometry(P, size_class(volume.shape) if max_axis is None else max_axis)
    n_rays = plan.shape[0] * plan.shape[1]
    if n_rays > geo.max_rays:
        raise _refuse(f"{n_rays} base-plane rays", "view", f"<= {geo.max_rays} rays")
    if arch.slice_overhead_cycles:
        raise _refuse(
            f"{arch.name} adds {arch.slice_overhead_cycles} clocks between slices; the RTL "
            "top's slices follow each other back to back (a what-if of the cycle rung only)",
            "overheads.slice_cycles",
            "0",
            arch.source,
        )
    fifo = machine.capacity["pixel_fifo_entries"]
    if fifo < 1:
        raise _refuse(
            "a pixel FIFO of depth 0 never accepts a pixel (the frame deadlocks)",
            "buffers.pixel_fifo_entries",
            ">= 1",
            arch.source,
        )
    nz, ny, nx = volume.shape
    cx = -(-nx // P)
    loads: list[tuple[int, int, int]] = []

    volume_words = _volume_words(backend.raw, P, dp.voxel_bits)

    mode = scene.render.mode
    if mode == "composite":
        lut, c = backend.lut, dp.classify.color_bits
        entry = lut.rgb[:, 0] | lut.rgb[:, 1] << c | lut.rgb[:, 2] << 2 * c | lut.alpha << 3 * c
        loads += [(LOAD_LUT, i, int(e)) for i, e in enumerate(entry)]
        k = float(plan._dt) / backend.ref
        table = composite_unit.correction_table(int(dp.composite.ratio.quantize(k)), dp.composite)
        loads += [(LOAD_CORRECTION, i, int(e)) for i, e in enumerate(table)]
    modulate = mode == "composite" and backend.need_grad and transfer.modulates
    if modulate:
        loads += [(LOAD_GM, i, int(e)) for i, e in enumerate(backend.gm_table)]
    lit = mode == "composite" and scene.lit
    if lit:
        loads += _shader_loads(backend.shader)

    # Ray table: first and last step of every base-plane ray (never for unused ones).
    rlay = ray_layout(geo)
    never = (1 << geo.axis_bits) - 1
    j_lo = np.full(n_rays, never, dtype=np.int64)
    j_hi = np.zeros(n_rays, dtype=np.int64)
    j_lo[plan.ray_ids], j_hi[plan.ray_ids] = plan.j_lo, plan.j_hi
    loads += [
        (LOAD_RAYS, r, _pack(rlay, {"j_lo": j_lo[r], "j_hi": j_hi[r]})) for r in range(n_rays)
    ]

    slices = _slice_constants(machine, plan, j_lo, j_hi, scene.crop)
    slay = slice_layout(geo, dp)
    loads += [(LOAD_SLICES, j, _pack(slay, rec)) for j, rec in enumerate(slices)]

    ert = backend.ert
    registers = {
        **_shading_registers(backend, dp, lit, modulate),
        "n_kp": machine.n_kp,
        "n_a": machine.n_a,
        "n_b": machine.n_b,
        "nx": nx,
        "ny": ny,
        "cx": cx,
        "kp": machine.kp,
        "forward": int(machine.forward),
        "c": machine.C,
        "fifo_depth": fifo,
        "width": plan.shape[1],
        "height": plan.shape[0],
        "mip": int(mode == "mip"),
        "ert_enable": int(mode == "composite" and ert < 1.0),
        "ert_threshold": int(dp.composite.acc.quantize(min(max(ert, 0.0), 1.0))),
        "crop": int(scene.crop is not None),
        "crop_needed": scene.crop.slabs_needed if scene.crop is not None else 0,
        "crop_invert": int(scene.crop is not None and scene.crop.invert),
    }
    units = ["memory", "ring", *elaborate_units(backend, ())[0][:-1], "pixel_bus"]
    return FrameProgram(
        geo=geo,
        backend=backend,
        loads=loads,
        registers=registers,
        volume_words=volume_words,
        elaborated=units,
    )


def _volume_words(raw: np.ndarray, P: int, B: int) -> list[int]:
    """The voxel memory's contents in the Cube-4 skewed layout (``models.units.skew``):
    word ``w`` holds module ``k``'s voxel at its word ``w`` in bits ``k B``."""
    nz, ny, nx = raw.shape
    z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    module = skew.cube4_module(x, y, z, P).ravel()
    word = skew.cube4_address_zyx(z, y, x, raw.shape, P).ravel()
    voxels = np.asarray(raw, dtype=np.int64).ravel()
    fields = np.zeros((nz * ny * -(-nx // P), P), dtype=np.int64)
    fields[word, module] = voxels
    words = [0] * fields.shape[0]
    for k in range(P):  # Python ints: P B may exceed 64 bits
        column = fields[:, k].tolist()
        words = [w | (v << (k * B)) for w, v in zip(words, column, strict=True)]
    return words


def _shader_loads(shader) -> list[tuple[int, int, int]]:
    """The shader's tables: the reflectance maps (diffuse, specular: one entry per cube
    cell, the lights summed in, ``models.units.shade.setup``) or Phong's specular table."""
    if shader.maps is not None:
        diffuse, specular = shader.maps
        return [(LOAD_DIFFUSE_MAP, i, int(e)) for i, e in enumerate(diffuse)] + [
            (LOAD_SPEC, i, int(e)) for i, e in enumerate(specular)
        ]
    return [(LOAD_SPEC, i, int(e)) for i, e in enumerate(shader.spec)]


def _shading_registers(backend: Backend, dp: Datapath, lit: bool, modulate: bool) -> dict:
    """Gradient, modulation and shading registers (zeros where the scene does not use
    them; unused lights have intensity 0, which adds exactly nothing).  A reflectance-map
    shader has only ``ka``: its lights are in the maps."""
    f = dp.shade.normal_frac_bits
    spacing_xyz = np.asarray(backend.volume.spacing, dtype=np.float64)[::-1]
    ratio = np.floor(spacing_xyz.min() / spacing_xyz * 4096 + 0.5).astype(np.int64)
    regs = {
        "lit": int(lit),
        "modulate": int(modulate),
        "gm_scale": int(backend.gm_scale) if modulate else 0,
        "ratio": _fields([int(r) for r in ratio], 13),
        "ka": int(backend.shader.ka) if lit else 0,
    }
    if dp.shade.method != "phong":
        return regs
    regs.update(kd=0, ks=0, light=0, half=0, intensity=0)
    if lit:
        sh = backend.shader
        k = sh.light.shape[0]
        pad = [[0, 0, 0]] * (MAX_LIGHTS - k)
        regs.update(
            kd=sh.kd,
            ks=sh.ks,
            light=_fields([c for v in [*sh.light.tolist(), *pad] for c in v], f + 2),
            half=_fields([c for v in [*sh.half.tolist(), *pad] for c in v], f + 2),
            intensity=_fields([*sh.intensity.tolist(), *[0] * (MAX_LIGHTS - k)], 12),
        )
    return regs


def _fields(values: list[int], width: int) -> int:
    """Two's-complement ``width``-bit fields packed first at bit 0."""
    word = 0
    for i, value in enumerate(values):
        word |= (int(value) & ((1 << width) - 1)) << (i * width)
    return word


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
                raise _refuse(
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
                raise _refuse(f"step {j}: the crop box cuts the slice", "view", "another view")
            out["crop_k"] = int(inside[0])
            continue
        c = cells[name]
        lo_c, hi_c = (int(c[inside].min()), int(c[inside].max())) if inside.any() else (1, 0)
        if not np.array_equal(inside, (c >= lo_c) & (c <= hi_c)):
            raise _refuse(
                f"step {j}: the crop box's {name} slab is not a range of cells (float rounding)",
                "view",
                "another view",
            )
        out[f"crop_{name}_lo"], out[f"crop_{name}_hi"] = lo_c, hi_c
    return out


def _slice_constants(
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
    period = T  # slices back to back (an overhead is refused above)
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
                raise _refuse(
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
            raise _refuse(
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
            raise _refuse(
                f"step {j}: a ray's samples {gap.min()} clocks apart, the compositing "
                f"buffer needs {RMW_WINDOW}",
                "volume",
                "a larger volume",
            )
        last_issue[ray[takes]] = issue
        out.append(rec)
    return out


def decode(
    program: FrameProgram,
    pixels: list[dict[str, Any]],
    cycles: int,
    samples: int,
    stall_cycles: int | None = None,
):
    """The frame's :class:`~models.machines.cube4.cycle.CycleResult` from the delivered pixels.

    ``pixels``: ``{"ray", "acc" (4 ints), "mip"}`` in bus order.  Every ray of the plan
    must arrive exactly once; the host builds the image only from them.
    """
    be, plan = program.backend, program.plan
    state = be.new_state(plan.n_rays)
    acc, touched = state.acc, np.zeros(plan.n_rays, dtype=bool)
    for p in pixels:
        r = int(p["ray"])
        if r >= plan.n_rays or touched[r]:
            raise RuntimeError(f"pixel bus delivered ray {r} unexpectedly")
        touched[r] = True
        acc[r] = p["mip"] if be.mode == "mip" else p["acc"]
    delivered = np.flatnonzero(touched)
    if not np.array_equal(delivered, np.sort(plan.ray_ids)):
        raise RuntimeError(
            f"pixel bus delivered {delivered.size} rays, the plan has {plan.ray_ids.size}"
        )
    image = be.finish(acc, touched, None)
    counters = {
        "frame.cycles": int(cycles),
        "frame.samples": int(samples),
        "pixel_bus.pixels": len(pixels),
        **({} if stall_cycles is None else {"pixel_bus.stall_cycles": int(stall_cycles)}),
    }
    return CycleResult(
        image=image,
        samples=int(samples),
        rays=int(touched.sum()),
        cycles=int(cycles),
        counters=counters,
        elaborated_units=list(program.elaborated),
        elided_units=list(program.elided),
    )
