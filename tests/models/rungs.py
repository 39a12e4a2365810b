"""What the rung tests of tests/models share: one scene builder, one way to run two rungs
on the same plan, and the two comparisons they make (bit-identical images; cycle counts
within the transaction rung's contract).

Each test module keeps only what is particular to its machine (its arch variants, its
phantom sizes); the rungs are always called through the same entry points a render uses.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import (
    CropSpec,
    CutPlane,
    RenderSpec,
    Scene,
    TransferSpec,
    ViewSpec,
    VolumeSpec,
)
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from models.functional import render_functional
from models.transaction import render_transaction

#: The scene features a machine's cycle rung keeps bit-identical to the functional rung
#: (test id -> :func:`scene_of` extras); a machine's test may replace or add entries.
FEATURE_VARIANTS = {
    "pre-classified": {"transfer": TransferSpec(preset="ct", order="pre")},
    "crop": {"crop": CropSpec(x=(3.0, 15.0), y=(2.0, 18.0), z=(0.0, 12.5))},
    "cut-plane": {
        "cut_planes": (CutPlane(normal=(1.0, 0.3, 0.2), offset=0.5, thickness=4.0, falloff=2.0),)
    },
    "gm-modulation": {
        "transfer": TransferSpec(preset="ct", gradient_opacity=((0.0, 0.2), (200.0, 1.0)))
    },
    "unlit": {"render": {"lighting": False}},
    "ert": {"render": {"early_termination": 0.9}},
}

#: Format overrides of the compiled-kernel tests (test_cycle_fused, test_functional_fused):
#: a narrow interpolator rounding to nearest-even, and a wide datapath that truncates.
NARROW_NEAREST_EVEN = {
    "interp.weight_bits": 5,
    "interp.rounding": "nearest-even",
    "interp.sample_frac_bits": 2,
}
WIDE_TRUNCATE = {
    "interp.weight_bits": 16,
    "interp.sample_frac_bits": 12,
    "interp.rounding": "truncate",
    "gradient.normal_frac_bits": 4,
    "composite.acc_frac_bits": 12,
    "classify.entries": 256,
}

#: Issue 5: transaction cycle counts within 2 % of the cycle rung.
CONTRACT = 0.02

#: The grid the contract tests of the machines that skip work sweep: each phantom, both
#: projections, with and without early ray termination and space leaping.
skipping_grid = pytest.mark.parametrize(
    ("phantom", "projection", "ert", "leaping"),
    list(
        itertools.product(
            ("head", "ball", "marschner-lobb"),
            ("parallel", "perspective"),
            (1.0, 0.95),
            (False, True),
        )
    ),
)


def scene_of(
    az=30,
    el=20,
    *,
    phantom="head",
    size=28,
    mode="composite",
    projection="parallel",
    preset="ct",
    zoom=1.2,
    render=None,
    volume=None,
    **extra,
) -> Scene:
    """A square view of a phantom (or of ``volume``, a VolumeSpec that replaces
    ``phantom``); ``render`` holds further RenderSpec fields, ``extra`` further Scene fields
    (crop, cut planes, a transfer that replaces ``preset``)."""
    return Scene(
        volume=volume or VolumeSpec(phantom=phantom),
        transfer=extra.pop("transfer", TransferSpec(preset=preset)),
        view=ViewSpec(
            azimuth=az, elevation=el, width=size, height=size, zoom=zoom, projection=projection
        ),
        render=RenderSpec(mode=mode, **(render or {})),
        **extra,
    )


def sized_phantom_scene(view=(30, 15), projection="parallel", mode="composite", size=32):
    """A ``size``-square view of the head phantom built at ``size`` voxels, CT preset, no
    zoom: the early machines' tests (Cube-3, VOGUE) render at the volume's own size."""
    return Scene(
        volume=VolumeSpec(phantom="head", params=(("size", size),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(
            azimuth=view[0], elevation=view[1], width=size, height=size, projection=projection
        ),
        render=RenderSpec(mode=mode),
    )


def real_32(volume, z0: int):
    """A 32^3 cut of a real scan (``read_volume``'s result): every second slice from
    ``z0`` and every ``n / 32``-th row and column."""
    step = volume.data.shape[1] // 32
    data = volume.data[z0 : z0 + 64 : 2, ::step, ::step]
    return dataclasses.replace(volume, data=np.ascontiguousarray(data))


def phantom_set(head: int, ball: int, lobb: int) -> dict:
    """The three phantoms the contract tests sweep, at the sizes a machine wants."""
    return {
        "head": make_phantom("head", size=head),
        "ball": make_phantom("ball", size=ball),
        "marschner-lobb": make_phantom("marschner-lobb", size=lobb),
    }


def fault_scene(mode="composite", lighting=True, *, size=36, **extra) -> Scene:
    """The view the fault-injection tests break structures under."""
    return scene_of(35, 20, size=size, mode=mode, render={"lighting": lighting}, **extra)


def machine(arch: str | ArchConfig, **changes) -> ArchConfig:
    """A built-in machine (or ``arch`` itself) with fields replaced; ``buffers`` entries
    are merged into the machine's own."""
    base = resolve_arch(arch) if isinstance(arch, str) else arch
    if "buffers" in changes:
        changes["buffers"] = {**base.buffers, **changes["buffers"]}
    return dataclasses.replace(base, **changes) if changes else base


def prepared(scene, volume, arch):
    """(machine, transfer, plan) as a render prepares them."""
    arch = machine(arch)
    return arch, resolve_transfer(scene.transfer, volume), make_plan(scene, volume, arch.order)


def functional_and_cycle(scene, volume, arch, **kw):
    """(functional result, cycle result, plan) of one scene on one plan; ``kw`` goes to
    the cycle rung (faults, trace)."""
    arch, tf, plan = prepared(scene, volume, arch)
    fixed = render_functional(frame_of(scene, volume, tf, arch, plan))
    return fixed, render_cycle(frame_of(scene, volume, tf, arch, plan), **kw), plan


def cycle_and_transaction(scene, volume, arch):
    """(cycle result, transaction result) of one scene on one plan."""
    arch, tf, plan = prepared(scene, volume, arch)
    exact = render_cycle(frame_of(scene, volume, tf, arch, plan))
    return exact, render_transaction(frame_of(scene, volume, tf, arch, plan))


def within_contract(scene, volume, arch):
    """:func:`cycle_and_transaction`, asserting the transaction rung's frame cycles are
    within the contract of the cycle rung's."""
    exact, approx = cycle_and_transaction(scene, volume, arch)
    assert_within_contract(exact.cycles, approx.cycles)
    return exact, approx


def assert_identical(fixed, cycle):
    """The cycle image is the functional image, bit for bit, and the frame's sample
    counts are equal (a frame's ``samples`` are its planned samples on every rung)."""
    assert cycle.image.dtype == fixed.image.dtype and cycle.image.shape == fixed.image.shape
    assert np.array_equal(cycle.image, fixed.image), "cycle image differs from functional"
    assert cycle.samples == fixed.samples


def assert_within_contract(exact_cycles: int, approx_cycles: int, contract=CONTRACT):
    assert abs(approx_cycles - exact_cycles) <= contract * exact_cycles, (
        exact_cycles,
        approx_cycles,
    )


#: The real volumes' grid of the skipping machines' slow contract tests: each file, with
#: neither skip or both, in both projections.
real_volume_grid = pytest.mark.parametrize(
    ("name", "ert", "leaping", "projection"),
    [
        (name, ert, leaping, projection)
        for name in ("ct_cranium.nrrd", "mr_brainsmall.nrrd")
        for ert, leaping in ((1.0, False), (0.95, True))
        for projection in ("parallel", "perspective")
    ],
)


def assert_counters_equal(exact, approx, keys) -> None:
    """The counters the event model must share with the cycle rung exactly."""
    for key in keys:
        assert approx.counters[key] == exact.counters[key], key


def assert_slice_counters_add_up(cycle, plan, pipelines: int, units) -> None:
    """A slice machine's frame: no memory conflict, at most P samples a clock, one pixel per
    ray, and every listed unit of every pipeline busy, stalled or idle on every clock."""
    c = cycle.counters
    assert c["memory.conflicts"] == 0
    assert cycle.samples <= pipelines * cycle.cycles
    assert c["pixel_bus.pixels"] == plan.ray_ids.size
    for unit in units:
        for lane in range(pipelines):
            parts = [c[f"pipeline[{lane}].{unit}.{k}_cycles"] for k in ("busy", "stall", "idle")]
            assert sum(parts) == cycle.cycles, (unit, lane, parts)
