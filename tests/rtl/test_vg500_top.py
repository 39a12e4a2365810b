"""The vg500 top (rtl/vg500/top.py) on Amaranth's simulator: a frame goes from the SDRAM
devices through the four controllers, the de-skew and the slab buffer into the pipelines
and the pixel bus; the image is bit-identical to the cycle rung's, the devices' pins break
no datasheet rule (tests/rtl/sdram_standin.py), and every burst the cycle rung reads is
read once.  The cycles and held clocks are the cycle rung's too: since issue 35 its rules
for the VolumePro 500 are the published slice-FIFO structure's 3', 5', 8'
(models/machines/volumepro/fifo_timing.py, on the rung's own SDRAM scheduler), which
share no code with the top."""

import numpy as np
import pytest
from sdram_standin import StandInSdram

import hwsim
from hwsim.core.errors import InputError
from hwsim.studies.rtl_diff import _frame
from models.backend import Backend
from models.cycle import render_cycle
from models.machines.volumepro.cycle import SlabMachine
from models.machines.volumepro.fifo_timing import slice_fifo_timing
from rtl.vg500.frame import prepare_vg500
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


def test_what_the_top_does_not_render_is_refused_naming_the_key():
    scene = hwsim.load_scene(None, volume="head:size=8", image=8, mode="composite")
    with pytest.raises(InputError, match="lights"):
        prepare_vg500(_frame(scene, "volumepro500", None))
