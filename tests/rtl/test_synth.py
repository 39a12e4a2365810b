"""`hwsim rtl build`: Verilog of every unit, Yosys cell counts in synth.json, and the
bit-width trade priced in gates (a narrower datapath has fewer cells)."""

import json

import pytest

from hwsim.cli.commands import main
from rtl.build import UNITS, build, parse_settings

pytestmark = pytest.mark.synth


def test_build_all_writes_verilog_and_cells_for_every_unit(tmp_path, capsys, yosys):
    assert main(["rtl", "build", "all", "--out", str(tmp_path), "--quiet"]) == 0
    report = json.loads((tmp_path / "synth.json").read_text())
    assert report["schema"] == 1 and set(report["units"]) == set(UNITS)
    for unit, entry in report["units"].items():
        text = (tmp_path / f"{unit}.v").read_text()
        assert f"module {unit}(" in text.replace(" (", "(")
        assert entry["cells"] > 100 and entry["flip_flops"] > 0, unit
        assert entry["cells"] == sum(
            v for k, v in entry["cells_by_type"].items() if not k.startswith("$mem")
        )
    assert report["units"]["classify"]["memory_bits"] == 4096 * 36 + 64 * 13
    assert report["units"]["composite"]["memory_bits"] == 4097 * 13
    assert report["units"]["skew"]["memory_bits"] == 0


@pytest.mark.parametrize(
    ("unit", "key", "wide", "narrow"),
    [("interp", "weight_bits", 8, 4), ("skew", "max_size", 1024, 64)],
)
def test_a_narrower_width_costs_fewer_cells(tmp_path, unit, key, wide, narrow, yosys):
    cells = {}
    for bits in (wide, narrow):
        report = build([unit], tmp_path / str(bits), parse_settings([f"{unit}.{key}={bits}"]))
        assert report["units"][unit]["params"][key] == bits
        cells[bits] = report["units"][unit]["cells"]
    assert cells[narrow] < cells[wide]


def test_verilog_only_needs_no_yosys(tmp_path):
    assert main(["rtl", "build", "skew", "--out", str(tmp_path), "--no-synth", "--quiet"]) == 0
    assert (tmp_path / "skew.v").is_file() and not (tmp_path / "synth.json").exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["rtl", "build", "alu"], "UNIT: unknown unit 'alu' (allowed: all, skew"),
        (
            ["rtl", "build", "interp", "--set", "interp.weight=6"],
            "--set: interp.weight: unknown key",
        ),
        (["rtl", "build", "interp", "--set", "interp.weight_bits=six"], "is not an integer"),
        (["rtl", "build", "interp", "--set", "interp.weight_bits=40"], "weight_bits 1..16"),
        (["rtl", "build", "interp", "--set", "interp.voxel_bits=0"], "(allowed: 1 .. 16)"),
        (["rtl", "build", "skew", "--set", "interp.weight_bits=6"], "not being built"),
        (["rtl", "build", "all", "--set", "weight_bits=6"], "expected UNIT.KEY=VALUE"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    assert main([*argv, "--out", str(tmp_path), "--no-synth"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
