"""Scenes, views and the cycle-rung reference shared by the RTL-top tests (Amaranth and
cocotb tiers)."""

from __future__ import annotations

import dataclasses
from functools import cache

from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from rtl.frame import prepare

#: (arch, azimuth, elevation, mode, volume size), unlit: both architectures, parallel views
#: along each principal axis (z: 0,0; x: 90,0; y: 0,90) and an oblique one (the lit cases
#: below run the same datapath with shading on, in both slice orders).
TOP_CASES = [
    ("cube4", 0, 0, "composite", 12),
    ("cube4", 90, 0, "mip", 9),
    ("cube4-teramac", 0, 90, "composite", 8),
    ("cube4-teramac", 37, -61, "composite", 10),
]

#: Lit composite cases (gradient from neighbouring samples, Phong): each principal axis,
#: oblique views, either slice order, both architectures, a non-multiple of P.
LIT_CASES = [
    ("cube4", 30, 20, "lit", 8),
    ("cube4", 90, 0, "lit", 9),
    ("cube4-teramac", 0, 90, "lit", 8),
    ("cube4-teramac", 200, -35, "lit", 10),
]

#: Gradient-magnitude opacity modulation (value units per world unit -> opacity factor).
GRADIENT_OPACITY = ((0.0, 0.0), (40.0, 0.6), (400.0, 1.0))


def scene_of(
    az: float, el: float, mode: str, image: int = 12, modulate: bool = False, **render
) -> Scene:
    """The head phantom, CT preset; ``mode = "lit"`` is composite with the default light
    and Phong material, every other mode unlit; ``modulate``: gradient-opacity
    modulation."""
    lit = mode == "lit"
    transfer = TransferSpec(preset="ct", gradient_opacity=GRADIENT_OPACITY if modulate else None)
    return Scene(
        volume=VolumeSpec(phantom="head"),
        transfer=transfer,
        view=ViewSpec(azimuth=az, elevation=el, width=image, height=image, zoom=1.2),
        render=dataclasses.replace(
            RenderSpec(mode="composite" if lit else mode, **render), lighting=lit
        ),
    )


@cache
def case(
    arch: str,
    az: float,
    el: float,
    mode: str,
    size: int,
    modulate=False,
    pixel_fifo: int | None = None,
    spacing: tuple[float, float, float] | None = None,
    **render,
):
    """``(program, cycle-rung result)`` of one case; ``pixel_fifo``: the machine's
    ``buffers.pixel_fifo_entries``; ``spacing``: the volume's voxel spacing ``(z, y, x)``."""
    volume = make_phantom("head", size=size)
    if spacing is not None:
        volume = dataclasses.replace(volume, spacing=spacing)
    scene = scene_of(az, el, mode, modulate=modulate, **render)
    machine = resolve_arch(arch)
    if pixel_fifo is not None:
        machine = dataclasses.replace(machine, buffers={"pixel_fifo_entries": pixel_fifo})
    transfer = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    reference = render_cycle(frame_of(scene, volume, transfer, machine, plan))
    return prepare(frame_of(scene, volume, transfer, machine, plan)), reference
