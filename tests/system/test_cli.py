"""End-to-end `hwsim` runs: the output contract of design section 9 and the error contract."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_errors import run_cli

from hwsim.cli.commands import main

pytestmark = pytest.mark.system

STATS_KEYS = {
    "schema",
    "fidelity",
    "arch",
    "scene",
    "samples",
    "cycles",
    "clock_hz",
    "frame_seconds",
    "samples_per_second",
    "wall_seconds",
    "elaborated_units",
    "elided_units",
    "counters",
}


def test_render_writes_image_png_npy_and_stats(tmp_path):
    out = tmp_path / "run"
    status = main(
        [
            "render",
            "--phantom",
            "head:size=32",
            "--image",
            "40x30",
            "--view",
            "30,10",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert status == 0
    image = np.load(out / "image.npy")
    assert image.shape == (30, 40, 4) and image.dtype == np.float64
    assert np.isfinite(image).all() and 0 <= image.min() and image.max() <= 1
    assert image[..., 3].max() > 0.5  # the head is visible
    assert (out / "image.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    stats = json.loads((out / "stats.json").read_text())
    assert STATS_KEYS <= set(stats)
    assert stats["fidelity"] == "golden" and stats["cycles"] is None
    assert stats["samples"] > 0 and stats["wall_seconds"] > 0
    assert stats["scene"]["view"]["width"] == 40 and stats["scene"]["view"]["azimuth"] == 30
    assert "shade" in stats["elaborated_units"]


@pytest.mark.parametrize(
    ("mode", "elided"), [("mip", "shade"), ("xray", "classify"), ("minip", "gradient")]
)
def test_scalar_modes_write_2d_images_and_elide_units(tmp_path, mode, elided):
    out = tmp_path / mode
    assert (
        main(
            [
                "render",
                "--phantom",
                "ball:size=16",
                "--mode",
                mode,
                "--image",
                "24",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    image = np.load(out / "image.npy")
    assert image.shape == (24, 24)
    stats = json.loads((out / "stats.json").read_text())
    assert elided in stats["elided_units"]
    assert stats["scene"]["render"]["mode"] == mode


def test_default_render_uses_the_builtin_scene_and_prints_a_summary(tmp_path):
    proc = run_cli("render", "--image", "32", "--out", str(tmp_path / "d"))
    assert proc.returncode == 0, proc.stderr
    assert "head" in proc.stdout and "samples" in proc.stdout
    stats = json.loads((tmp_path / "d" / "stats.json").read_text())
    assert stats["scene"]["name"] == "head"


def test_scene_file_and_listing_commands(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(
        'schema = 1\n[volume]\nphantom = "ball"\nparams = { size = 12 }\n'
        '[render]\nmode = "xray"\n[view]\nwidth = 8\nheight = 8\n'
    )
    assert main(["render", str(scene), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert np.load(tmp_path / "o" / "image.npy").shape == (8, 8)
    listing = run_cli("scenes")
    assert listing.returncode == 0 and "head" in listing.stdout and "(default)" in listing.stdout
    phantoms = run_cli("phantoms")
    assert phantoms.returncode == 0 and "marschner-lobb" in phantoms.stdout


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["render", "--mode", "dvr"], "invalid choice"),
        (
            ["render", "--view", "400,0"],
            "--view: azimuth: out of range, got 400.0 (allowed: -360 .. 360)",
        ),
        (["render", "--view", "10"], "expected AZ,EL"),
        (["render", "--image", "0"], "--image: out of range, got 0 (allowed: 1 .. 4096)"),
        (["render", "--image", "axb"], "not an integer"),
        (["render", "--phantom", "teapot"], "teapot"),
        (["render", "--volume", "/nonexistent/x.nrrd"], "/nonexistent/x.nrrd"),
        (
            ["render", "--fidelity", "rtl", "--arch", "volumepro1000"],
            "--arch: volumepro1000 has no RTL top",
        ),
        (
            # Every machine has a transaction model now; it refuses what the machine did.
            [
                "render",
                "--fidelity",
                "transaction",
                "--arch",
                "volumepro500",
                "--projection",
                "perspective",
            ],
            "volumepro500 renders parallel projection only",
        ),
        (["render", "--trace", "t.vcd"], "--trace: a waveform needs --fidelity cycle"),
        (["render", "--arch", "cray-1"], "--arch: unknown architecture 'cray-1'"),
        (
            ["render", "--arch", "volumepro500", "--projection", "perspective"],
            "volumepro500 renders parallel projection only",
        ),
        (["render", "no-such-scene"], "unknown built-in scene"),
        (["trade", "--rungs", "fast", "--out", "x"], "--rungs: unknown rung 'fast'"),
        (["sweep", "missing.toml"], "missing.toml: file not found"),
    ],
)
def test_bad_input_is_one_line_on_stderr_with_exit_status_2(tmp_path, args, needle):
    proc = run_cli(*args, "--out", str(tmp_path / "x")) if args[0] == "render" else run_cli(*args)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert needle in lines[0]
    assert "Traceback" not in proc.stderr


def test_malformed_scene_file_names_file_and_key(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text("[render]\nmode = 'composite'\nsample_spacing = -1\n")
    proc = run_cli("render", str(scene), "--out", str(tmp_path / "x"))
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        f"hwsim: error: {scene}: render.sample_spacing: out of range, got -1"
        " (allowed: 0.0625 .. 16)"
    )


def test_unwritable_output_folder_is_bad_input(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    proc = run_cli(
        "render", "--phantom", "ball:size=8", "--image", "8", "--out", str(blocker / "sub")
    )
    assert proc.returncode == 2 and "--out" in proc.stderr


@pytest.mark.parametrize("volume", ["ct_cranium.nrrd", "mr_brainsmall.nrrd"])
@pytest.mark.parametrize("mode", ["composite", "mip", "minip", "xray", "iso"])
def test_real_volumes_render_in_every_mode(tmp_path, shared_data, volume, mode):
    out = tmp_path / mode
    assert (
        main(
            [
                "render",
                "--volume",
                str(shared_data / volume),
                "--mode",
                mode,
                "--image",
                "48",
                "--view",
                "180,10",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    image = np.load(out / "image.npy")
    assert np.isfinite(image).all()
    if mode in ("composite", "iso"):
        coverage = (image[..., 3] > 0.1).mean()
        assert 0.05 < coverage < 0.95, coverage  # an object on a background, not blank or full
    else:
        assert image.max() > image.min()  # structure, not a constant
