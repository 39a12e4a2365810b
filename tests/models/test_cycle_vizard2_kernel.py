"""VIZARD II's compiled ray loop (models/machines/vizard2/ray_kernel.py) gives the unit
chain's image, cycles, samples and every counter.

Each frame is rendered twice on one plan: with the kernel (``compiled=True``, the
default; a spy checks it ran) and with the reference unit chain (``compiled=False``).
The cases cover every fault VIZARD II has (stuck SDRAM word and bank, corrupted and
dropped cache fills, a shallow ray queue and pixel FIFO), its features (early ray
termination with and without the machine's feedback, space leaping on and off, MIP,
perspective, gradient modulation, anisotropic voxels, unlit), pipeline counts, cache,
tile and memory-clock variants.  Frames outside the kernel's scope take the chain.
"""

from __future__ import annotations

import numpy as np
import pytest
import rungs

from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import CropSpec, TransferSpec
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from models.machines.vizard2 import ray_kernel
from models.machines.vizard2.config import VizardFaults

pytestmark = pytest.mark.model

MODULATED = TransferSpec(preset="ct", gradient_opacity=((100.0, 0.0), (1500.0, 1.0)))
MEMORY = resolve_arch("vizard2").memory


def _scene(az=35, el=20, mode="composite", **kw):
    return rungs.scene_of(az, el, size=kw.pop("size", 24), mode=mode, **kw)


#: id -> (scene, arch changes, faults, volume)
CASES = {
    "composite": (_scene(), {}, None, "head"),
    "mip": (_scene(mode="mip"), {}, None, "head"),
    "ert": (_scene(render={"early_termination": 0.8}), {}, None, "head"),
    "ert-no-feedback": (
        _scene(render={"early_termination": 0.8}),
        {"early_termination": False},
        None,
        "head",
    ),
    "no-leaping": (_scene(az=-120, el=-30), {"space_leaping": False}, None, "head"),
    "modulated-ert": (
        _scene(transfer=MODULATED, render={"early_termination": 0.6}),
        {},
        None,
        "head",
    ),
    "unlit": (_scene(render={"lighting": False}), {}, None, "head"),
    "anisotropic": (_scene(az=-60, el=30), {}, None, "head-z"),
    "perspective-unlit": (
        _scene(az=20, el=-15, projection="perspective", render={"lighting": False}),
        {},
        None,
        "head",
    ),
    "perspective-mip": (
        _scene(az=80, el=10, mode="mip", projection="perspective"),
        {},
        None,
        "head",
    ),
    "P3-small-cache": (
        _scene(az=140, el=35),
        {"pipelines": 3, "buffers": {"cache_sets": [2, 2, 2], "ray_tile": [4, 8]}},
        None,
        "head",
    ),
    "slow-memory": (_scene(), {"memory": {**MEMORY, "clock_ratio": 0.7}}, None, "head"),
    "closed-page-fast-memory": (
        _scene(az=10, el=70),
        {"memory": {**MEMORY, "clock_ratio": 1.5, "page_policy": "closed", "t_refi": 90}},
        None,
        "head",
    ),
    "stuck-word": (_scene(mode="mip"), {}, VizardFaults(stuck_word=(500, 30000)), "head"),
    "stuck-bank": (_scene(), {}, VizardFaults(stuck_bank=(0, 0)), "head"),
    "corrupt-line": (_scene(), {}, VizardFaults(corrupt_line=(5, 0x7FF)), "head"),
    "dropped-fill": (_scene(), {}, VizardFaults(dropped_fill=3), "head"),
    "dropped-fill-mip": (_scene(mode="mip"), {}, VizardFaults(dropped_fill=40), "head"),
    "short-queue-shallow-fifo": (
        _scene(render={"early_termination": 0.9}),
        {},
        VizardFaults(ray_queue_entries=5, pixel_fifo_depth=1),
        "head",
    ),
}


@pytest.fixture(scope="module")
def volumes():
    return {
        "head": make_phantom("head", size=19),  # odd: edge blocks are partial
        "head-z": make_phantom("head", size=18, z_spacing=1.7),
    }


def _both(scene, volume, arch, faults):
    arch, tf, plan = rungs.prepared(scene, volume, arch)
    runs = [
        render_cycle(frame_of(scene, volume, tf, arch, plan), faults=faults, compiled=compiled)
        for compiled in (True, False)
    ]
    return runs


@pytest.mark.parametrize("case", CASES)
def test_kernel_equals_the_unit_chain(volumes, monkeypatch, case):
    scene, changes, faults, volume = CASES[case]
    ran = []
    run_frame = ray_kernel.RayKernel.run_frame

    def spy(self, *args):
        ran.append(True)
        return run_frame(self, *args)

    monkeypatch.setattr(ray_kernel.RayKernel, "run_frame", spy)
    arch = rungs.machine("vizard2", **changes)
    fast, slow = _both(scene, volumes[volume], arch, faults)
    assert ran == [True]  # the kernel ran once (the chain for compiled=False)
    assert np.array_equal(fast.image, slow.image)
    assert (fast.cycles, fast.samples, fast.rays) == (slow.cycles, slow.samples, slow.rays)
    assert fast.counters == slow.counters
    assert fast.samples > 0 and fast.counters["cache.misses"] > 0


def test_a_fault_reaches_the_kernels_image(volumes):
    """The comparison above can fail: a corrupted line changes the kernel's image."""
    scene = _scene()
    clean, _ = _both(scene, volumes["head"], "vizard2", None)
    broken, _ = _both(scene, volumes["head"], "vizard2", VizardFaults(corrupt_line=(5, 0x7FF)))
    assert not np.array_equal(clean.image, broken.image)
    assert clean.cycles == broken.cycles


@pytest.mark.parametrize(
    "scene",
    [
        _scene(crop=CropSpec(x=(3.0, 15.0))),
        _scene(projection="perspective"),  # lit: a shader per ray
        _scene(mode="iso"),
    ],
    ids=["crop", "perspective-lit", "iso"],
)
def test_frames_outside_the_scope_take_the_chain(volumes, scene):
    arch, tf, plan = rungs.prepared(scene, volumes["head"], "vizard2")
    frame = frame_of(scene, volumes["head"], tf, arch, plan)
    from models.backend import Backend
    from models.machines.vizard2.cycle import VizardMachine

    assert ray_kernel.RayKernel.for_machine(VizardMachine(Backend(frame))) is None
    run = render_cycle(frame)  # and still renders
    assert run.samples > 0


@pytest.mark.parametrize("faults", [None, VizardFaults(ray_queue_entries=5, pixel_fifo_depth=1)])
def test_one_call_a_frame_equals_one_call_a_packet(volumes, faults):
    """The loop runs a frame's packets in one call, the pixel FIFO in it; with a progress
    report it runs one call a packet, the FIFO in Python: the same image, cycles and
    counters (and the report counts every packet)."""
    scene = _scene(render={"early_termination": 0.9})
    arch, tf, plan = rungs.prepared(scene, volumes["head"], "vizard2")
    frame = frame_of(scene, volumes["head"], tf, arch, plan)
    seen = []
    whole = render_cycle(frame, faults=faults)
    packets = render_cycle(frame, faults=faults, progress=lambda k, n: seen.append((k, n)))
    assert np.array_equal(whole.image, packets.image)
    assert (whole.cycles, whole.counters) == (packets.cycles, packets.counters)
    assert len(seen) > 1 and seen[-1][0] == seen[-1][1] == len(seen)
    assert whole.counters["pixel_bus.pixels"] == whole.rays
