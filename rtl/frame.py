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
are then *checked* against it (:mod:`rtl.frame_slices`); the tables, registers and
word packing are :mod:`rtl.frame_tables`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.errors import NotAvailableError
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
from rtl.frame_slices import geometry_loads, refuse
from rtl.frame_tables import shading_registers, table_loads, voxel_memory_words
from rtl.top_layouts import TopGeometry, load_layout
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
        raise refuse(
            "the RTL top renders parallel views (per-slice constants); perspective is "
            "modelled at the cycle rung only",
            "view.projection",
            "parallel",
            scene.source if hasattr(scene, "source") else None,
        )
    if max(volume.shape) > MAX_AXIS:
        raise refuse(
            f"volume {volume.shape[::-1]} is too big for the RTL top",
            "volume",
            f"at most {MAX_AXIS} voxels per axis",
        )
    if min(volume.shape) < 4:
        raise refuse(
            f"volume {volume.shape[::-1]} is too small for the RTL top", "volume", ">= 4 per axis"
        )
    mode = scene.render.mode
    if mode not in ("composite", "mip"):
        raise refuse(f"mode {mode!r} is not in the RTL top", "render.mode", "composite, mip")
    if scene.lit and dp.shade.method == "phong" and len(scene.lights) > MAX_LIGHTS:
        raise refuse(
            f"{len(scene.lights)} lights; the RTL top's shader sums {MAX_LIGHTS}",
            "lights",
            f"at most {MAX_LIGHTS} lights",
        )
    if mode == "composite" and transfer.order == "pre":
        raise refuse("the RTL top post-classifies", "transfer.order", "post")
    if scene.cursor is not None:
        raise refuse("the RTL top has no cursor unit", "cursor", "no [cursor]")
    if scene.render.blend_order != "front-to-back":
        raise refuse(
            "the RTL top's compositor blends front to back", "render.blend_order", "front-to-back"
        )
    if scene.cut_planes:
        raise refuse("the RTL top's crop unit has no cut planes", "cut_planes", "none")
    if mode == "composite" and scene.lit and transfer.modulates_illumination:
        raise refuse(
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
        raise refuse(f"{n_rays} base-plane rays", "view", f"<= {geo.max_rays} rays")
    if arch.slice_overhead_cycles:
        raise refuse(
            f"{arch.name} adds {arch.slice_overhead_cycles} clocks between slices; the RTL "
            "top's slices follow each other back to back (a what-if of the cycle rung only)",
            "overheads.slice_cycles",
            "0",
            arch.source,
        )
    fifo = machine.capacity["pixel_fifo_entries"]
    if fifo < 1:
        raise refuse(
            "a pixel FIFO of depth 0 never accepts a pixel (the frame deadlocks)",
            "buffers.pixel_fifo_entries",
            ">= 1",
            arch.source,
        )
    nz, ny, nx = volume.shape
    cx = -(-nx // P)
    volume_words = voxel_memory_words(backend.raw, P, dp.voxel_bits)
    mode = scene.render.mode
    loads, lit, modulate = table_loads(scene, transfer, plan, backend, dp)
    loads += geometry_loads(machine, plan, geo, dp, scene.crop)
    ert = backend.ert
    registers = {
        **shading_registers(backend, dp, lit, modulate),
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
