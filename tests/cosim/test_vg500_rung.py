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
from hwsim.studies.rtl_diff import VG500_COUNTERS, CounterDiff, RtlDiff, _frame, rtl_diff
from models.backend import Backend
from models.cycle import render_cycle
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


def test_a_lit_frame_shades_with_the_reflectance_maps_bit_identically(tmp_path):
    """The default scene's light, the VolumePro 500's own reflectance maps (64 x 64 cells
    a face, loaded by the host) on the vg500 top: the cycle rung's image, samples and
    bursts; the cycles are the slice-FIFO rules' (docs/rtl.md)."""
    require("verilator")
    lit = [*SCENE[:3], "composite", *SCENE[4:]]
    outs = {}
    for fidelity in ("rtl", "cycle"):
        argv = ["render", *lit, "--fidelity", fidelity, "--arch", "volumepro500"]
        assert main([*argv, "--out", str(tmp_path / fidelity), "--quiet"]) == 0
        outs[fidelity] = json.loads((tmp_path / fidelity / "stats.json").read_text())
    images = [np.load(tmp_path / d / "image.npy") for d in ("rtl", "cycle")]
    assert np.array_equal(*images) and images[0].any()
    rtl, cyc = outs["rtl"], outs["cycle"]
    assert rtl["samples"] == cyc["samples"]
    assert rtl["counters"]["memory.bursts"] == cyc["counters"]["memory.bursts"]
    assert rtl["counters"]["memory.sdram.checker.violations"] == 0
    scene = hwsim.load_scene(None, volume="head:size=8", view=(30, 20), image=8)
    rules = slice_fifo_timing(SlabMachine(Backend(_frame(scene, "volumepro500", None))))
    assert (rtl["cycles"], rtl["counters"]["memory.hold_cycles"]) == (
        rules.cycles,
        rules.stall_cycles,
    )


def test_rtl_diff_compares_the_vg500_tops_counts_with_the_cycle_rungs(capsys):
    """``hwsim rtl diff --arch volumepro500``: image, samples, cycles, memory waits and
    the SDRAM's bursts, activations and refreshes, each from its own side; exit 0 only
    when all agree."""
    require("verilator")
    scene = hwsim.load_scene(None, volume="head:size=8", view=(30, 20), image=8, mode="mip")
    report = rtl_diff(scene, arch="volumepro500")
    assert report.streams == [] and report.images_equal
    counts = {c.name: c for c in report.counters}
    assert set(counts) == {name for name, _, _ in VG500_COUNTERS}
    assert counts["samples"].equal and counts["SDRAM bursts"].equal
    assert counts["SDRAM bursts"].rtl == 64 and counts["memory wait clocks"].rtl > 0
    cycle = render_cycle(_frame(scene, "volumepro500", None))
    assert report.cycle_cycles == cycle.cycles
    assert counts["memory wait clocks"].cycle == cycle.counters["memory.stall_cycles"]
    argv = ["rtl", "diff", "--arch", "volumepro500", *SCENE]
    status = main(argv)
    out = capsys.readouterr().out
    assert status == (0 if report.identical else 1)
    assert f"cycles: rtl {report.rtl_cycles}, cycle rung {report.cycle_cycles}" in out
    assert "images bit-identical" in out and "SDRAM bursts: 64 in both" in out
    assert counts["SDRAM refreshes"].equal  # the frame's, not the table loads'


def test_a_count_that_differs_fails_the_diff_and_says_by_how_much():
    differs = RtlDiff(277, 277, True, counters=[CounterDiff("SDRAM refreshes", 3, 0)])
    assert not differs.identical
    assert differs.lines()[-1] == "SDRAM refreshes: rtl 3, cycle rung 0 (+3)"
    same = RtlDiff(277, 277, True, counters=[CounterDiff("SDRAM bursts", 64, 64)])
    assert same.identical and same.lines()[1:] == ["SDRAM bursts: 64 in both", "no difference"]
    assert not RtlDiff(277, 279, True, counters=same.counters).identical
