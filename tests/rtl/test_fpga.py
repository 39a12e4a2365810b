"""`hwsim rtl fpga`: a unit synthesised for an ECP5 by Yosys and placed and routed by
nextpnr-ecp5 (the `fpga` extra), its fpga.json, and the refusals before any work."""

import json

import pytest
from cli_errors import one_line_error

import rtl.fpga
from hwsim.cli.commands import main
from rtl.fpga import parse_device


def test_a_part_number_becomes_nextpnr_flags():
    device = parse_device("LFE5U-85F-6BG381C")
    assert device.args() == ["--85k", "--package", "CABGA381", "--speed", "6"]
    assert parse_device("lfe5um5g-45f-8bg554i").args()[:2] == ["--um5g-45k", "--package"]


@pytest.mark.parametrize(
    ("part", "fragment"),
    [("XC7A35T", "unknown device 'XC7A35T'"), ("LFE5UM-12F-6BG381C", "no LFE5UM of 12k")],
)
def test_an_unknown_part_is_one_line(tmp_path, capsys, part, fragment):
    argv = ["rtl", "fpga", "skew", "--device", part, "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    one_line_error(capsys, "--device", fragment)
    assert not (tmp_path / "o").exists()


def test_a_missing_tool_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(rtl.fpga.TOOLS, "nextpnr", "hwsim-no-such-nextpnr")
    assert main(["rtl", "fpga", "skew", "--out", str(tmp_path)]) == 2
    one_line_error(capsys, "hwsim-no-such-nextpnr is not installed", "pip install 'hwsim[fpga]'")
    assert not (tmp_path / "fpga.json").exists() and not (tmp_path / "skew.v").exists()


def test_an_output_folder_that_is_a_file_is_refused_before_any_work(tmp_path, capsys):
    target = tmp_path / "taken"
    target.write_text("mine")
    assert main(["rtl", "fpga", "skew", "--out", str(target)]) == 2
    one_line_error(capsys, "--out")
    assert target.read_text() == "mine"


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["rtl", "fpga", "alu"], "TARGET: unknown target 'alu'"),
        (["rtl", "fpga", "skew", "--set", "interp.weight_bits=6"], "--set names interp"),
    ],
)
def test_a_bad_target_or_setting_is_one_line(tmp_path, capsys, argv, fragment):
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    one_line_error(capsys, fragment)


@pytest.mark.synth
@pytest.mark.slow
def test_the_skew_unit_places_and_routes_with_a_positive_fmax(tmp_path, capsys):
    assert main(["rtl", "fpga", "skew", "--out", str(tmp_path)]) == 0
    assert "skew on LFE5U-85F-6BG381C: fmax" in capsys.readouterr().out
    record = json.loads((tmp_path / "fpga.json").read_text())
    assert record["device"] == "LFE5U-85F-6BG381C" and record["target"] == "skew"
    assert record["fmax_mhz"] > 1.0
    assert record["luts"] > 20 and record["ffs"] >= 40  # skew's 49 pipeline flip-flops
    assert record["brams"] == 0 and record["dsps"] >= 0
    assert record["machine"] == "cube4" and record["machine_clock_mhz"] == 125.0
    assert "Yosys" in record["tools"]["yosys"] and "nextpnr" in record["tools"]["nextpnr"]
    for log in rtl.fpga.LOGS:
        assert (tmp_path / log).stat().st_size > 0, log
    report = json.loads((tmp_path / "nextpnr-report.json").read_text())
    assert report["utilization"]["TRELLIS_FF"]["used"] == record["ffs_routed"]
    assert record["ffs_routed"] == record["ffs"] + record["port_register_bits"]
    assert "what_if_frame_rate" not in record  # a unit is not a machine


@pytest.mark.synth
@pytest.mark.slow
def test_a_design_larger_than_the_device_names_its_utilisation(tmp_path, capsys):
    # The classify unit at 16-bit voxels: 65536-entry tables, more block RAM than a 12k part.
    argv = ["rtl", "fpga", "classify", "--device", "LFE5U-12F-6BG256C"]
    argv += ["--set", "classify.voxel_bits=16", "--set", "classify.entries=65536"]
    assert main([*argv, "--out", str(tmp_path), "--quiet"]) == 2
    one_line_error(capsys, "the design does not fit: it uses DP16KD 128/56")
    assert not (tmp_path / "fpga.json").exists()
