"""The vg500 top (rtl/vg500/top.py) on Amaranth's simulator: a frame goes from the SDRAM
devices through the four controllers, the de-skew and the slab buffer into the pipelines
and the pixel bus; the image is bit-identical to the cycle rung's, the devices' pins break
no datasheet rule (tests/rtl/sdram_standin.py), and every burst the cycle rung reads is
read once.  The cycles and held clocks are the cycle rung's too: since issue 35 its rules
for the VolumePro 500 are the published slice-FIFO structure's 3', 5', 8'
(models/machines/volumepro/fifo_timing.py, on the rung's own SDRAM scheduler), which
share no code with the top."""

import dataclasses

import numpy as np
import pytest
from sdram_standin import StandInSdram

import hwsim
from hwsim.core.errors import InputError
from hwsim.run.fidelity import builtin_archs, machine_rungs, resolve_arch
from hwsim.spec.scene import CropSpec
from hwsim.studies.rtl_diff import _frame
from models.backend import Backend
from models.cycle import render_cycle
from models.machines.volumepro.cycle import SlabMachine
from models.machines.volumepro.fifo_timing import slice_fifo_timing
from rtl.top_layouts import LOAD_DIFFUSE_MAP
from rtl.vg500.frame import is_vg500, prepare_vg500
from rtl.vg500.sim import run_vg500_amaranth

pytestmark = pytest.mark.rtl

PINS = ("cs_n", "ras_n", "cas_n", "we_n", "ba", "a")


def frame(size=8, mode="mip", view=(30, 20), **kw):
    scene = hwsim.load_scene(None, volume=f"head:size={size}", view=view, image=size, mode=mode)
    if kw:
        scene = scene.replace(render=scene.render.__class__(**{**scene.render.__dict__, **kw}))
    return _frame(scene, "volumepro500", None)


@pytest.mark.parametrize("view", [(30, 20), (100, 10), (210, 20)])  # the last: back to front
def test_a_frame_through_sdram_matches_the_cycle_rungs_image(view):
    f = frame(view=view)
    program = prepare_vg500(f)
    devices = [StandInSdram(program.timing, {}) for _ in range(4)]

    def check(ctx, top, clock):
        for k, dev in enumerate(devices):
            dev.sample(clock, *(ctx.get(getattr(top, f"sdram{k}_{p}")) for p in PINS))

    result, out = run_vg500_amaranth(program, on_clock=check)
    cycle = render_cycle(f)
    assert np.array_equal(np.asarray(result.image), np.asarray(cycle.image))
    assert result.samples == cycle.samples
    assert out["bursts"] == cycle.counters["memory.bursts"]
    for dev in devices:
        assert dev.violations == []
        assert dev.counts["READ"] == out["bursts"] // 4
    assert result.cycles > out["hold_cycles"] > 0
    rules = slice_fifo_timing(SlabMachine(Backend(f)))
    assert (result.cycles, out["hold_cycles"]) == (rules.cycles, rules.stall_cycles)
    assert (result.cycles, out["hold_cycles"]) == (
        cycle.cycles,
        cycle.counters["memory.stall_cycles"],
    )


def test_a_lit_frame_shades_with_the_reflectance_maps_as_the_cycle_rung_does():
    """The default scene's light on the VolumePro 500's reflectance-map shader: the host
    loads both maps (here 4 x 4 cells a face: 2 x 97 entries, the simulator's load clocks
    kept short), the image is the cycle rung's and differs from the unlit one."""
    f = frame(mode="composite")
    assert f.scene.lit and f.datapath.shade.method == "reflectance-map"
    dp = f.datapath
    f = dataclasses.replace(
        f, datapath=dataclasses.replace(dp, shade=dataclasses.replace(dp.shade, map_size=4))
    )
    program = prepare_vg500(f)
    assert sum(t == LOAD_DIFFUSE_MAP for t, _, _ in program.inner.loads) == 6 * 4 * 4 + 1
    assert "light" not in program.inner.registers  # the lights are in the maps
    result, out = run_vg500_amaranth(program)
    cycle = render_cycle(f)
    assert np.array_equal(np.asarray(result.image), np.asarray(cycle.image))
    unlit = render_cycle(frame(mode="composite", lighting=False))
    assert not np.array_equal(np.asarray(unlit.image), np.asarray(cycle.image))
    rules = slice_fifo_timing(SlabMachine(Backend(f)))
    assert (result.cycles, out["hold_cycles"]) == (rules.cycles, rules.stall_cycles)


def test_what_the_top_does_not_render_is_refused_naming_the_key():
    with pytest.raises(InputError, match="supersampling"):
        prepare_vg500(frame(supersampling=2.0))
    scene = hwsim.load_scene(None, volume="head:size=8", image=8, mode="composite")
    scene = scene.replace(
        transfer=dataclasses.replace(scene.transfer, gradient_illumination=((0, 0), (1, 1)))
    )
    with pytest.raises(InputError, match="gradient_illumination"):
        prepare_vg500(_frame(scene, "volumepro500", None))


def test_the_family_declares_the_rtl_rung_for_the_archs_the_top_renders():
    """models.machines.volumepro.machine.vg500_shaped (the rung's declaration, which may
    not import the RTL) and rtl.vg500.frame.is_vg500 (the top's own test) agree."""
    archs = [resolve_arch(name) for name in builtin_archs()]
    base = resolve_arch("volumepro500")
    archs += [
        dataclasses.replace(base, pipelines=8),
        dataclasses.replace(base, memory={**base.memory, "modules": 8}),
        dataclasses.replace(base, memory={**base.memory, "skew": "block"}),
        dataclasses.replace(base, order="shear-image"),
    ]
    for arch in archs:
        declared = "rtl" in machine_rungs(arch) and arch.family == "volumepro"
        assert declared == is_vg500(arch), arch.name
    assert is_vg500(base) and "rtl" in machine_rungs(base)
    assert "rtl" not in machine_rungs(resolve_arch("volumepro1000"))


def test_em_cube_renders_lit_on_the_same_top_with_its_phong_shader():
    """EM-Cube (also four modules, shear-warp, mini-block skew: the family declares the
    rtl rung for it too) shades per sample with Phong; the same top, its shader's method
    from the datapath."""
    scene = hwsim.load_scene(None, volume="head:size=8", view=(30, 20), image=8)
    f = _frame(scene, "em-cube", None)
    assert f.scene.lit and f.datapath.shade.method == "phong"
    program = prepare_vg500(f)
    assert "light" in program.inner.registers
    result, out = run_vg500_amaranth(program)
    cycle = render_cycle(f)
    assert np.array_equal(np.asarray(result.image), np.asarray(cycle.image))
    assert result.samples == cycle.samples and out["bursts"] == cycle.counters["memory.bursts"]
    rules = slice_fifo_timing(SlabMachine(Backend(f)))
    assert (result.cycles, out["hold_cycles"]) == (rules.cycles, rules.stall_cycles)


@pytest.mark.parametrize(
    ("mode", "crop"),
    [
        ("mip", CropSpec(x=(1.5, 5.2), y=(2.0, 6.0), z=(0.0, 4.5))),
        ("composite", CropSpec(x=(1.5, 5.2), y=(2, 6), z=(0, 4.5), mode="cross", invert=True)),
    ],
)
def test_the_crop_unit_keeps_the_samples_the_cycle_rung_keeps(mode, crop):
    """VolumePro 500's crop box (three slabs, sub-volume / cross / fence, inverted): the
    host writes each slice's slabs as cell ranges, checked against the plan's positions;
    the unit's comparators gate the write-back, so a cropped ray still leaves the bus."""
    f = frame(mode=mode)
    f = dataclasses.replace(f, scene=f.scene.replace(crop=crop))
    dp = f.datapath
    f = dataclasses.replace(
        f, datapath=dataclasses.replace(dp, shade=dataclasses.replace(dp.shade, map_size=4))
    )
    result, out = run_vg500_amaranth(prepare_vg500(f))
    cycle = render_cycle(f)
    assert np.array_equal(np.asarray(result.image), np.asarray(cycle.image))
    assert result.samples == cycle.samples < render_cycle(frame(mode=mode)).samples
    waits = cycle.counters["memory.stall_cycles"]
    assert (result.cycles, out["hold_cycles"]) == (cycle.cycles, waits)
