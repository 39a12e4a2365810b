"""Area and clock three ways: each unit placed and routed on an ECP5
(``hwsim/energy/data/units_fpga.json``, ``python -m hwsim.studies.fpga``) reaches
stats.json and the report beside the table estimate and the ASIC synthesis."""

from __future__ import annotations

import json

import pytest

from hwsim.cli.commands import main
from hwsim.energy.fpga import fpga_measured, unit_fpga
from hwsim.report.energy import energy_blocks
from rtl.build import UNITS


def test_every_unit_was_routed_with_the_command_that_repeats_it():
    data = fpga_measured()
    assert set(data["units"]) == set(UNITS)
    for unit, entry in data["units"].items():
        assert entry["fmax_mhz"] > 0 and entry["luts"] > 0 and entry["ffs"] > 0, unit
        assert entry["device"] == data["device"] and entry["rtl_commit"], unit
        assert entry["command"].startswith(f"hwsim rtl fpga {unit} --device "), unit


def test_a_missing_unit_is_not_routed():
    assert unit_fpga("crop") is None
    gradient = unit_fpga("gradient", 125e6)
    assert gradient["fmax_hz"] == pytest.approx(
        fpga_measured()["units"]["gradient"]["fmax_mhz"] * 1e6
    )
    assert gradient["meets_clock"] is (gradient["fmax_hz"] >= 125e6)


@pytest.mark.system
def test_stats_and_the_report_show_the_routed_fmax_beside_the_estimate(tmp_path):
    out = tmp_path / "r"
    argv = ["render", "--fidelity", "cycle", "--arch", "volumepro500", "--phantom"]
    assert main([*argv, "head:size=16", "--image", "16", "--out", str(out), "--quiet"]) == 0
    stats = json.loads((out / "stats.json").read_text())
    interp = stats["area"]["units"]["interp"]
    routed = fpga_measured()["units"]["interp"]
    assert interp["fpga"]["fmax_hz"] == pytest.approx(routed["fmax_mhz"] * 1e6)
    assert interp["fpga"]["luts"] == routed["luts"] and interp["synthesized"]["fmax_hz"]
    (table,) = [
        b for b in energy_blocks(stats, tmp_path, 1, "-") if b[0] == "table" and "unit" in b[1]
    ]
    header, rows = table[1], table[2]
    assert header[-2:] == ["FPGA LUT/FF/DSP/BRAM", "routed fmax MHz (ECP5)"]
    row = next(r for r in rows if r[0] == "interp")
    assert row[-2].split("/")[0] == str(routed["luts"])
    assert row[-1] == format(routed["fmax_mhz"], ".0f")


def test_archs_ends_with_each_units_routed_fmax(capsys):
    assert main(["archs"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert "placed and routed on an LFE5U-85F" in last
    for unit, entry in fpga_measured()["units"].items():
        assert f"{unit} {entry['fmax_mhz']:.0f} MHz" in last


def test_each_routed_top_carries_its_what_if_marked_as_one():
    for name, top in fpga_measured()["tops"].items():
        if "error" in top:
            assert top["error"] and top["command"].startswith("hwsim rtl fpga"), name
            continue
        assert top["fmax_mhz"] > 0 and top["luts"] > 0 and top["dsps"] > 0, name
        what = top["what_if"]
        assert "not a published machine" in what["what"]
        assert top["what_if_frame_rate"] == pytest.approx(top["fmax_mhz"] * 1e6 / what["cycles"])
        assert what["teramac_clock_mhz"] == 0.96
