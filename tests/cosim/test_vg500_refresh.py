"""The vg500 top's SDRAM refreshes on Verilator fall in the frame's phase: its controllers
restart their refresh interval at the frame's first request (rtl/vg500/sdram_ctrl.py), as
the cycle rung's scheduler counts its refreshes from the frame's clock 0, so the refreshes
the four datasheet checkers see between the frame's start and its last READ are the cycle
rung's count, and the activations (rows opened again after each refresh) are equal too.
Counted from power-up (the controllers' old phase), a 16^3 frame refreshed at frame clocks
~462 and ~1 418: 8 refreshes and 32 activations against the cycle rung's 4 and 25."""

from __future__ import annotations

import numpy as np
import pytest
from simulators import require

import hwsim
from hwsim.studies.rtl_diff import _frame
from models.cycle import render_cycle
from rtl.vg500.frame import prepare_vg500
from rtl.vg500.rung import run_vg500

pytestmark = pytest.mark.cosim


def test_a_16_cubed_frames_refreshes_and_activations_are_the_cycle_rungs():
    require("verilator")
    scene = hwsim.load_scene(None, volume="head:size=16", view=(30, 15), image=16, mode="mip")
    frame = _frame(scene, "volumepro500", None)
    rtl, _ = run_vg500(prepare_vg500(frame))
    cycle = render_cycle(frame)
    c, k = rtl.counters, cycle.counters
    assert c["memory.sdram.checker.violations"] == 0
    assert k["memory.sdram.refreshes"] > 0  # the frame is longer than t_refi
    assert c["memory.sdram.frame_refreshes"] == k["memory.sdram.refreshes"]
    assert c["memory.sdram.checker.refreshes"] >= c["memory.sdram.frame_refreshes"]
    assert c["memory.sdram.checker.activates"] == k["memory.sdram.activates"]
    assert (rtl.cycles, c["memory.hold_cycles"]) == (cycle.cycles, k["memory.stall_cycles"])
    assert np.array_equal(np.asarray(rtl.image), np.asarray(cycle.image))
