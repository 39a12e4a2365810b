"""``hwsim rtl diff``: the RTL top's and the cycle rung's period starts, frozen clocks and
pixel pops agree event by event; a cycle-rung rule one clock off is found at its first
pixel, with exit status 1."""

from __future__ import annotations

import dataclasses

import pytest
from simulators import require
from top_cases import scene_of

import models.machines.cube4.timing as timing
from hwsim.cli.commands import main
from hwsim.run.fidelity import resolve_arch
from hwsim.studies.rtl_diff import rtl_diff
from hwsim.volumes import make_phantom

pytestmark = pytest.mark.cosim


def _shallow():
    return dataclasses.replace(resolve_arch("cube4"), buffers={"pixel_fifo_entries": 3})


def test_rungs_agree_event_by_event_with_frozen_clocks():
    require("verilator")
    report = rtl_diff(scene_of(30, 20, "lit"), arch=_shallow(), volume=make_phantom("head", size=8))
    assert report.identical, report.lines()
    by_name = {s.name: s for s in report.streams}
    assert by_name["F"].rtl_count > 0  # the FIFO did fill: freezes compared one by one
    assert by_name["S"].rtl_count == 9 and by_name["P"].rtl_count == 120
    assert report.lines()[-1] == "no difference"


def test_a_rule_one_clock_off_is_found_at_its_first_pixel(monkeypatch, capsys):
    require("verilator")
    real = timing.cube4_latency
    monkeypatch.setattr(timing, "cube4_latency", lambda c: real(c) + 1)
    report = rtl_diff(scene_of(30, 20, "lit"), volume=make_phantom("head", size=8))
    assert not report.identical
    pops = {s.name: s for s in report.streams}["P"]
    assert pops.first_index == 0
    assert pops.cycle[0] == pops.rtl[0] + 1 and pops.cycle[1] == pops.rtl[1]
    assert report.first_clock == pops.rtl[0]
    argv = ["rtl", "diff", "--phantom", "head:size=8", "--view", "30,20", "--image", "12"]
    assert main(argv) == 1
    out = capsys.readouterr().out
    assert f"first difference at frame clock {pops.rtl[0]}" in out
