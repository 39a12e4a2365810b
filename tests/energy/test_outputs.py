"""Energy and area reach what users read: stats.json, units.csv, memory.csv, the render
summary, ``hwsim archs``; a bad ``--technology`` is a one-line error before any work."""

from __future__ import annotations

import csv
import json

import pytest

from hwsim.cli.commands import main

pytestmark = pytest.mark.system


def test_a_cycle_render_writes_energy_and_area(tmp_path, capsys):
    out = tmp_path / "r"
    argv = ["render", "--fidelity", "cycle", "--arch", "volumepro500", "--phantom"]
    argv += ["head:size=24", "--image", "24", "--technology", "cmos45", "--out", str(out)]
    assert main(argv) == 0
    assert "nJ/sample" in capsys.readouterr().out
    stats = json.loads((out / "stats.json").read_text())
    assert stats["technology"]["name"] == "cmos45"
    assert stats["technology"]["file"] == "hwsim/energy/technologies/cmos45.toml"
    energy, area = stats["energy"], stats["area"]
    assert energy["total_joules"] > energy["dynamic_joules"] > 0
    assert set(energy["units"]) <= {"interp", "gradient", "classify", "shade", "composite"}
    assert area["total_mm2"] > 0 and area["units"]["gradient"]["synthesized"]["logic_levels"]
    classify = area["units"]["classify"]["synthesized"]  # area two ways, logic and storage apart
    assert classify["logic_mm2"] + classify["storage_mm2"] == pytest.approx(classify["mm2"])
    assert classify["table_storage_bits"] > 0 and "shared" in classify["independence"]
    assert classify["fmax_basis"].startswith("estimate")
    with open(out / "units.csv") as fh:
        rows = list(csv.DictReader(fh))
    interp = [r for r in rows if r["unit"] == "interp"]
    assert len(interp) == 4 and all(float(r["energy_joules"]) > 0 for r in interp)
    total = sum(float(r["energy_joules"]) for r in interp)
    assert total == pytest.approx(energy["units"]["interp"]["joules"])
    memory = (out / "memory.csv").read_text()
    assert "energy.dram.joules" in memory and "area.slab_buffer.mm2" in memory


def test_a_golden_render_has_no_energy(tmp_path):
    out = tmp_path / "g"
    argv = ["render", "--phantom", "head:size=16", "--image", "16", "--out", str(out)]
    assert main([*argv, "--quiet"]) == 0
    stats = json.loads((out / "stats.json").read_text())
    assert stats["energy"] is None and stats["area"] is None


def test_an_unknown_technology_is_refused_before_the_frame(tmp_path, capsys):
    argv = ["render", "--fidelity", "cycle", "--arch", "cube4", "--technology", "cmos9"]
    assert main([*argv, "--out", str(tmp_path / "x"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--technology" in err[0] and "cmos45" in err[0]
    assert not (tmp_path / "x" / "stats.json").exists()


def test_archs_lists_no_unit_below_its_machines_clock(capsys):
    """Every unit is pipelined to its machine's clock (issue 34): the slow-unit list that
    `hwsim archs` prints (tested with a faster clock in test_energy.py) is absent."""
    assert main(["archs"]) == 0
    text = capsys.readouterr().out
    assert "node" in text and "cmos350" in text
    assert "estimated below" not in text and "estimated slower" not in text
