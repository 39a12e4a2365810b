"""The cycle rung's compiled composite stages give the unit chain's bits: Cube-4's
(models/machines/cube4/slice_kernel.py) and the VolumePro family's
(models/machines/volumepro/slab_kernel.py).

Whole cycle frames rendered with the kernel (``compiled=True``, the default) equal the
vectorised unit chain (``compiled=False``) in image, samples, cycles and every counter,
over both Cube-4 machines (and three pipelines), views along an axis, at 45 degrees and from behind,
anisotropic voxels, modulation and early termination, crop and cut planes, narrow and
wide formats, several pipeline counts and every injected fault that changes the data the
kernel reads (a stuck module, a dropped ring link, a short beam or slice FIFO, a lost
hand-off); the kernel ran on each.  Frames outside its scope take the chain.  Its cache
key covers the shared stage it inlines.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs

from hwsim.core.threads import using
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import CropSpec, CutPlane, Light, RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models import fused, fused_stage
from models.cycle import render_cycle
from models.datapath import Datapath
from models.frame import frame_of
from models.machines.cube4 import slice_kernel
from models.machines.cube4.cycle import Faults
from models.machines.volumepro import slab_kernel
from models.machines.volumepro.cycle import SlabFaults

pytestmark = pytest.mark.model


def _scene(az=30, el=20, size=32, transfer=None, **kw):
    return Scene(
        transfer=transfer or TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=size, height=size, zoom=1.3),
        render=RenderSpec(**{"mode": "composite", **kw.pop("render", {})}),
        **kw,
    )


MODULATED = TransferSpec(preset="ct", gradient_opacity=((100.0, 0.0), (1500.0, 1.0)))
CUT = (CutPlane(normal=(0.3, 0.2, 1.0), offset=1.0, thickness=6, falloff=3),)


def _case(arch, scene, volume="head", overrides=None, faults=None, **changes):
    """(machine, changes to it, volume, scene, format overrides, faults)."""
    return arch, changes, volume, scene, overrides or {}, faults


#: :func:`_case` of each frame; every one runs the kernel.
CASES = {
    "cube4": _case("cube4", _scene()),
    "cube4-axis": _case("cube4", _scene(az=0, el=0)),
    "cube4-45-45": _case("cube4", _scene(az=45, el=45)),
    "cube4-back": _case("cube4", _scene(az=180, el=-35)),
    "cube4-x-principal": _case("cube4", _scene(az=95, el=-5), volume="head-z"),
    "cube4-anisotropic": _case("cube4", _scene(az=-60, el=30), volume="head-z"),
    "cube4-modulated-ert": _case(
        "cube4", _scene(transfer=MODULATED, render={"early_termination": 0.7})
    ),
    "cube4-crop-cut": _case("cube4", _scene(crop=CropSpec(y=(4, 15), invert=True), cut_planes=CUT)),
    "cube4-unlit": _case("cube4", _scene(render={"lighting": False})),
    "cube4-two-lights": _case(
        "cube4",
        _scene(lights=(Light(direction=(-0.4, 0.5, 1.0)), Light(direction=(0.7, -0.2, 0.5)))),
    ),
    "cube4-P3": _case("cube4", _scene(az=-25, el=15), pipelines=3),
    "cube4-teramac": _case("cube4-teramac", _scene(az=70, el=-20)),
    "narrow-nearest-even": _case(
        "cube4",
        _scene(az=-70, el=25),
        overrides=rungs.NARROW_NEAREST_EVEN,
    ),
    "wide-truncate": _case(
        "cube4",
        _scene(transfer=MODULATED),
        overrides=rungs.WIDE_TRUNCATE,
    ),
    "stuck-module": _case("cube4", _scene(), faults=Faults(stuck_module=(1, 4095))),
    "dropped-link": _case("cube4", _scene(), faults=Faults(dropped_link=2)),
    "dropped-handoff": _case("cube4", _scene(), faults=Faults(dropped_handoff=0)),
    "short-beam-fifo": _case("cube4", _scene(), faults=Faults(beam_fifo_adjust=-1)),
    "short-slice-fifo": _case("cube4", _scene(), faults=Faults(slice_fifo_adjust=-1)),
    "tiny-pixel-fifo": _case("cube4", _scene(), faults=Faults(pixel_fifo_depth=1)),
}


#: The VolumePro family: trilinear samples, sample or voxel gradients, supersampling.
SLAB_CASES = {
    "vp500": _case("volumepro500", _scene()),
    "vp500-axis": _case("volumepro500", _scene(az=0, el=0)),
    "vp500-45-45": _case("volumepro500", _scene(az=45, el=45)),
    "vp500-back": _case("volumepro500", _scene(az=180, el=-35)),
    "vp500-y-principal": _case("volumepro500", _scene(az=10, el=80)),
    "vp500-x-principal": _case("volumepro500", _scene(az=95, el=-5), volume="head-z"),
    "vp500-anisotropic": _case("volumepro500", _scene(az=-60, el=30), volume="head-z"),
    "vp500-modulated": _case("volumepro500", _scene(transfer=MODULATED)),
    "vp500-crop": _case("volumepro500", _scene(crop=CropSpec(y=(4, 15), invert=True))),
    "vp500-supersampled": _case(
        "volumepro500", _scene(az=20, el=50, render={"supersampling": 2.0})
    ),
    # Sample slices between voxel slices along each principal axis: the trilinear paths.
    "vp500-supersampled-x": _case(
        "volumepro500", _scene(az=95, el=-5, render={"supersampling": 2.0}), volume="head-z"
    ),
    "vp500-supersampled-y": _case(
        "volumepro500", _scene(az=10, el=80, render={"supersampling": 2.0})
    ),
    "vp1000-supersampled-x": _case(
        "volumepro1000", _scene(az=95, el=-5, render={"supersampling": 2.0}), volume="head-z"
    ),
    "vp500-unlit": _case("volumepro500", _scene(render={"lighting": False})),
    "vp500-narrow": _case(
        "volumepro500",
        _scene(az=-70, el=25),
        overrides=rungs.NARROW_NEAREST_EVEN,
    ),
    "em-cube": _case("em-cube", _scene(az=100, el=10)),
    "vp1000-voxel-gradients": _case("volumepro1000", _scene(az=-20, el=60)),
    "vp1000-x-principal": _case("volumepro1000", _scene(az=95, el=-5), volume="head-z"),
    "vp1000-supersampled-cut": _case(
        "volumepro1000", _scene(cut_planes=CUT, render={"supersampling": 3.0})
    ),
    "vp500-stuck-module": _case(
        "volumepro500", _scene(), faults=SlabFaults(stuck_module=(1, 4095))
    ),
    "vp500-dropped-link": _case("volumepro500", _scene(), faults=SlabFaults(dropped_link=2)),
    "vp500-stuck-bank": _case("volumepro500", _scene(), faults=SlabFaults(stuck_bank=(0, 1, 3000))),
    "vp500-lost-handoff": _case("volumepro500", _scene(), faults=SlabFaults(dropped_handoff=1)),
    "vp500-short-beam-fifo": _case(
        "volumepro500", _scene(), faults=SlabFaults(beam_fifo_adjust=-1)
    ),
}


@pytest.fixture(scope="module")
def volumes():
    return {
        "head": make_phantom("head", size=21),
        "head-z": make_phantom("head", size=24, z_spacing=1.7),
    }


def _render(arch_name, changes, volume, scene, overrides, faults, **kw):
    arch = resolve_arch(arch_name)
    arch = dataclasses.replace(arch, **changes) if changes else arch
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, arch.order)
    dp = Datapath.from_arch(arch, volume.bits, overrides)
    frame = frame_of(scene, volume, tf, arch, plan, datapath=dp)
    return render_cycle(frame, faults=faults, **kw)


def _same(fast, ref):
    np.testing.assert_array_equal(fast.image, ref.image)
    assert (fast.samples, fast.rays, fast.cycles) == (ref.samples, ref.rays, ref.cycles)
    assert fast.counters == ref.counters


def _compiled_equals_unit_chain(kernel, case, volumes, monkeypatch):
    """``case`` rendered with ``kernel`` (counted: it must run) equals the unit chain."""
    arch, changes, volume, scene, overrides, faults = case
    runs = []
    original = kernel.run

    def counted(self, src, step, factor, state, table):
        runs.append(step.rays.size)
        return original(self, src, step, factor, state, table)

    monkeypatch.setattr(kernel, "run", counted)
    fast = _render(arch, changes, volumes[volume], scene, overrides, faults)
    assert sum(runs) > 0, "the kernel did not run"
    ref = _render(arch, changes, volumes[volume], scene, overrides, faults, compiled=False)
    _same(fast, ref)
    assert ref.image[..., 3].max() > 0.05  # something was composited


@pytest.mark.parametrize("case", list(CASES))
def test_compiled_cycle_frames_equal_the_unit_chain(case, volumes, monkeypatch):
    _compiled_equals_unit_chain(slice_kernel.SliceKernel, CASES[case], volumes, monkeypatch)


@pytest.mark.parametrize("case", list(SLAB_CASES))
def test_compiled_slab_frames_equal_the_unit_chain(case, volumes, monkeypatch):
    _compiled_equals_unit_chain(slab_kernel.SlabKernel, SLAB_CASES[case], volumes, monkeypatch)


def test_threads_split_steps_into_runs_with_the_same_bits(volumes, monkeypatch):
    """Steps above two runs' worth of samples are cut for the frame's threads."""
    monkeypatch.setattr(fused_stage, "_SAMPLES_PER_THREAD", 64)
    args = ("cube4", {}, volumes["head"], _scene(), {}, None)
    with using(1):
        one = _render(*args)
    with using(2):
        two = _render(*args)
    _same(two, one)


@pytest.mark.parametrize(
    "scene",
    [
        _scene(transfer=TransferSpec(preset="ct", order="pre")),
        _scene(render={"mode": "mip"}),
        Scene(
            transfer=TransferSpec(preset="ct"),
            view=ViewSpec(azimuth=-30, elevation=10, width=32, height=32, projection="perspective"),
        ),
    ],
    ids=["pre-classified", "mip", "perspective"],
)
def test_frames_outside_the_kernels_scope_take_the_unit_chain(scene, volumes, monkeypatch):
    runs = []
    original = slice_kernel.SliceKernel.run

    def counted(self, src, step, *rest):
        runs.append(step.rays.size)
        return original(self, src, step, *rest)

    monkeypatch.setattr(slice_kernel.SliceKernel, "run", counted)
    args = ("cube4", {}, volumes["head"], scene, {}, None)
    _same(_render(*args), _render(*args, compiled=False))
    assert not runs


def test_the_cache_key_covers_the_shared_stage():
    """The kernel inlines models/fused_stage.py's shading and blending: its closure holds the
    hash of that file and of every unit function (numba keys its cache by this module's
    source and the closure only)."""
    kernel = slice_kernel._kernel()
    assert kernel.py_func.__closure__ is not None
    held = [c.cell_contents for c in kernel.py_func.__closure__]
    assert fused.STAGE_HASH in held
