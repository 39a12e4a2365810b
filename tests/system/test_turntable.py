"""Turntables: ``hwsim render --frames N --turn DEG`` (issue 18)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from cli_errors import one_line_error
from PIL import Image

from hwsim.cli.commands import main
from hwsim.run.fidelity import render
from hwsim.run.turntable import _azimuth, render_turntable
from hwsim.spec.scene import VolumeSpec, load_scene
from hwsim.volumes import make_phantom

pytestmark = pytest.mark.system

HEAD = ["--phantom", "head:size=16", "--image", "16", "--quiet"]


def test_the_cli_writes_frames_a_gif_and_per_frame_times(tmp_path):
    out = tmp_path / "tt"
    assert main(["render", *HEAD, "--frames", "5", "--turn", "40", "--out", str(out)]) == 0
    stats = json.loads((out / "stats.json").read_text())
    block = stats["turntable"]
    assert block["frames"] == 5 and block["azimuths"] == [30.0, 70.0, 110.0, 150.0, -170.0]
    assert len(block["frame_wall_seconds"]) == 5 and block["median_of"] == "frames 2..N"
    assert stats["scene"]["view"]["azimuth"] == 30.0  # frame 1's stats
    assert sorted(p.name for p in (out / "frames").iterdir()) == [
        f"frame_{k:04d}.png" for k in range(5)
    ]
    with Image.open(out / "turntable.gif") as gif:
        assert gif.n_frames == 5 and gif.size == (16, 16) and gif.info["loop"] == 0


def test_each_frame_is_the_single_render_at_its_azimuth():
    scene = load_scene("head").replace(volume=VolumeSpec(phantom="head", params=(("size", 16),)))
    scene = scene.replace(view=dataclasses.replace(scene.view, width=16, height=16))
    volume = make_phantom("head", size=16)
    runs = render_turntable(scene, 3, 100.0, fidelity="cycle", arch="cube4", volume=volume)
    for run, azimuth in zip(runs, (30.0, 130.0, -130.0), strict=True):
        view = dataclasses.replace(scene.view, azimuth=azimuth)
        single = render(scene.replace(view=view), fidelity="cycle", arch="cube4", volume=volume)
        assert np.array_equal(run.image, single.image) and run.cycles == single.cycles


def test_scalar_frames_share_one_grey_window(tmp_path):
    out = tmp_path / "mip"
    args = ["render", *HEAD, "--mode", "mip", "--frames", "4", "--out", str(out)]
    assert main(args) == 0
    frames = []
    for path in sorted((out / "frames").iterdir()):
        with Image.open(path) as picture:
            frames.append(np.asarray(picture))
    assert max(int(f.max()) for f in frames) == 255
    assert min(int(f.min()) for f in frames) == 0


def test_azimuths_wrap_into_the_scene_range():
    assert _azimuth(170.0, 1, 30.0) == -160.0
    assert _azimuth(-170.0, 1, -30.0) == 160.0
    assert _azimuth(0.0, 12, 30.0) == 0.0


@pytest.mark.parametrize(
    ("extra", "key"),
    [
        (["--frames", "0"], "--frames"),
        (["--frames", "4000"], "--frames"),
        (["--frames", "3", "--turn", "nan"], "--turn"),
        (["--frames", "3", "--turn", "720"], "--turn"),
        (
            ["--frames", "2", "--fidelity", "cycle", "--arch", "cube4", "--trace", "w.vcd"],
            "--trace",
        ),
    ],
)
def test_bad_turntables_are_one_line_errors(tmp_path, capsys, extra, key):
    args = ["render", *HEAD, *extra, "--out", str(tmp_path / "x")]
    assert main([a.replace("w.vcd", str(tmp_path / "w.vcd")) for a in args]) == 2
    one_line_error(capsys, key)


def test_frames_stream_to_disk_and_are_not_kept(tmp_path, monkeypatch):
    """Issue 33: each frame's PNG is on disk before the next frame renders, and no image
    but frame 1's (its stats.json and image files are written at the end) stays alive."""
    import gc
    import weakref

    import hwsim.run.turntable as turntable

    out, images, checked = tmp_path / "tt", [], []

    def render_and_watch(*args, **kw):
        k = len(images)
        if k:
            assert (out / "frames" / f"frame_{k - 1:04d}.png").is_file(), k
            gc.collect()
            assert [ref() is None for ref in images[1:]] == [True] * (k - 1), k
            checked.append(k)
        run = render(*args, **kw)
        images.append(weakref.ref(run.image))
        return run

    monkeypatch.setattr(turntable, "render", render_and_watch)
    assert main(["render", *HEAD, "--frames", "5", "--out", str(out)]) == 0
    assert checked == [1, 2, 3, 4]
    assert len(list((out / "frames").iterdir())) == 5


def test_a_turntable_over_the_memory_budget_is_refused_before_its_first_frame(tmp_path, capsys):
    args = ["render", *HEAD, "--image", "4096", "--frames", "3000", "--max-memory", "64M"]
    assert main([*args, "--out", str(tmp_path / "tt")]) == 2
    one_line_error(capsys, "--frames", "memory budget")
