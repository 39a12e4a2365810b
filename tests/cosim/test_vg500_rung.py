"""The vg500 top's ``rtl`` rung on Verilator: ``hwsim render --fidelity rtl --arch
volumepro500`` of an 8^3 MIP frame gives the cycle rung's image and samples, every burst
the cycle rung reads, and the four ``rtl/sdram`` datasheet checkers on the top's pins find
no violation (their READ counts are the bursts).  The cycles and held clocks equal the
cycle rung's, whose rules for the VolumePro 500 are since issue 35 the slice-FIFO rules
3', 5', 8' (models/machines/volumepro/fifo_timing.py; docs/rtl.md, "The VolumePro 500
top")."""

from __future__ import annotations

import json

import numpy as np
import pytest
from simulators import require

import hwsim
from hwsim.cli.commands import main
from hwsim.studies.rtl_diff import _frame
from models.backend import Backend
from models.machines.volumepro.cycle import SlabMachine
from models.machines.volumepro.fifo_timing import slice_fifo_timing

pytestmark = pytest.mark.cosim
SCENE = ["--phantom", "head:size=8", "--mode", "mip", "--view", "30,20", "--image", "8"]


def _render(fidelity: str, out) -> dict:
    argv = ["render", *SCENE, "--fidelity", fidelity, "--arch", "volumepro500"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    return json.loads((out / "stats.json").read_text())


def test_render_rtl_of_the_vg500_matches_the_cycle_rung_with_a_legal_sdram(tmp_path):
    require("verilator")
    rtl = _render("rtl", tmp_path / "rtl")
    cyc = _render("cycle", tmp_path / "cycle")
    assert rtl["fidelity"] == "rtl" and rtl["samples"] == cyc["samples"]
    c = rtl["counters"]
    assert c["memory.sdram.checker.violations"] == 0
    assert c["memory.sdram.checker.reads"] == c["memory.bursts"] == cyc["counters"]["memory.bursts"]
    assert rtl["cycles"] > c["memory.hold_cycles"] > 0
    scene = hwsim.load_scene(None, volume="head:size=8", view=(30, 20), image=8, mode="mip")
    rules = slice_fifo_timing(SlabMachine(Backend(_frame(scene, "volumepro500", None))))
    assert (rtl["cycles"], c["memory.hold_cycles"]) == (rules.cycles, rules.stall_cycles)
    held = (cyc["cycles"], cyc["counters"]["memory.stall_cycles"])
    assert (rtl["cycles"], c["memory.hold_cycles"]) == held
    images = [np.load(tmp_path / d / "image.npy") for d in ("rtl", "cycle")]
    assert np.array_equal(*images)
