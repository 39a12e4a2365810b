"""The bit-width trade: files written, and error that falls as widths grow."""

from __future__ import annotations

import json

import pytest

from hwsim.cli.commands import main
from hwsim.run.fidelity import resolve_arch
from hwsim.studies.trade import default_cases, width_trade, write_width_trade
from hwsim.studies.trade.widths import pareto_front

pytestmark = pytest.mark.model


@pytest.fixture(scope="module")
def rows():
    knobs = {"gradient.normal_frac_bits": [4, 8, 10, 12, 14], "interp.weight_bits": [2, 4, 8]}
    return width_trade(default_cases([], 32), resolve_arch("volumepro500"), knobs)


def test_more_bits_never_cost_accuracy(rows):
    """Regression: the shader once read 10-bit normals whatever the gradient unit made,
    so 12-bit normals scored 16 dB against 45 dB at 10 bits."""
    for knob in ("gradient.normal_frac_bits", "interp.weight_bits"):
        series = [r["psnr_db"] for r in rows if r["knob"] == knob]
        assert all(b >= a - 0.5 for a, b in zip(series, series[1:], strict=False)), series
        assert series[-1] >= 40.0


def test_more_bits_cost_more_area_and_energy(rows):
    """Next to the error each width has its price: a wider knob never costs less area or
    less unit energy per sample (the machine's own node)."""
    for knob in ("gradient.normal_frac_bits", "interp.weight_bits"):
        series = [r for r in rows if r["knob"] == knob]
        assert all(r["technology"] == "cmos350" for r in series)
        for a, b in zip(series, series[1:], strict=False):
            assert b["area_mm2"] > a["area_mm2"]
            assert b["unit_energy_per_sample_joules"] > a["unit_energy_per_sample_joules"]


def test_the_pareto_front_keeps_only_unbeaten_points():
    points = [(1.0, 30.0), (2.0, 29.0), (2.0, 35.0), (3.0, 35.0), (4.0, 50.0), (0.5, 10.0)]
    assert pareto_front(points) == [(0.5, 10.0), (1.0, 30.0), (2.0, 35.0), (4.0, 50.0)]


def test_trade_writes_csv_json_and_plot(rows, tmp_path):
    paths = write_width_trade(rows, tmp_path)
    assert paths["png"].read_bytes()[:4] == b"\x89PNG"
    assert paths["pareto"].read_bytes()[:4] == b"\x89PNG"
    data = json.loads(paths["json"].read_text())
    assert len(data["rows"]) == len(rows) and {"knob", "value", "psnr_db"} <= set(data["rows"][0])
    assert paths["csv"].read_text().count("\n") == len(rows) + 1


def test_cli_width_trade_with_a_volume_file(tmp_path, shared_data, capsys):
    out = tmp_path / "w"
    status = main(
        [
            "trade",
            "--widths",
            "--volume",
            str(shared_data / "mr_brainsmall.nrrd"),
            "--image",
            "16",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert status == 0
    scenes = {r["scene"] for r in json.loads((out / "widths.json").read_text())["rows"]}
    assert scenes == {"marschner-lobb", "mr_brainsmall"}
