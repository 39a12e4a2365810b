"""The ``rtl`` rung end to end: ``hwsim render --fidelity rtl`` of a lit composite scene
(the default lighting: gradients and Phong shading in the RTL) on Verilator and Icarus
gives the cycle rung's image and cycle count; bad requests are one-line errors, exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
from simulators import require

from hwsim.cli.commands import main

pytestmark = pytest.mark.cosim
SCENE = ["--phantom", "head:size=8", "--mode", "composite", "--view", "30,20", "--image", "12"]


@pytest.fixture(scope="module")
def cycle_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cycle")
    assert (
        main(
            [
                "render",
                *SCENE,
                "--fidelity",
                "cycle",
                "--arch",
                "cube4",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    return out


@pytest.mark.parametrize("sim", ["verilator", "icarus"])
def test_render_rtl_equals_render_cycle(sim, cycle_run, tmp_path):
    require(sim)
    argv = ["render", *SCENE, "--fidelity", "rtl", "--arch", "cube4", "--simulator", sim]
    assert main([*argv, "--out", str(tmp_path), "--quiet"]) == 0
    rtl = json.loads((tmp_path / "stats.json").read_text())
    cyc = json.loads((cycle_run / "stats.json").read_text())
    assert rtl["fidelity"] == "rtl" and rtl["cycles"] == cyc["cycles"]
    assert rtl["samples"] == cyc["samples"]
    assert rtl["counters"]["rtl.simulator"] == sim
    assert np.array_equal(np.load(tmp_path / "image.npy"), np.load(cycle_run / "image.npy"))
    assert "shade" in rtl["elaborated_units"] and "gradient" in rtl["elaborated_units"]


def test_a_missing_simulator_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PATH", str(tmp_path))  # no iverilog anywhere
    argv = ["render", *SCENE, "--fidelity", "rtl", "--arch", "cube4", "--simulator", "icarus"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "simulator icarus not found" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--phantom", "head:size=130"], "at most 128 voxels per axis"),
        (["--arch", "volumepro1000"], "has no RTL top"),
        (["--projection", "perspective"], "view.projection"),
        (["--fidelity", "cycle", "--simulator", "icarus"], "--simulator: an HDL simulator"),
    ],
)
def test_what_the_rtl_rung_refuses_is_one_line_and_exit_2(tmp_path, capsys, extra, message):
    argv = ["render", *SCENE, "--fidelity", "rtl", "--arch", "cube4", *extra]
    assert main([*argv, "--out", str(tmp_path), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
