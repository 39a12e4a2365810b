"""`hwsim render --workers N`: one Cube-4 cycle frame split across a local Dask cluster.

The frame equals the one-process render bit for bit (image, cycles, counters), its
stats.json says how it was split, one progress bar covers every band, a worker killed
mid-band is replaced and its band rerun with the frame still identical, and what cannot
be split is refused in one line before any cluster starts.
"""

from __future__ import annotations

import json
import os
import signal

import numpy as np
import pytest

from hwsim.cli.commands import main

pytestmark = pytest.mark.system

ARGS = ["render", "--phantom", "head:size=32", "--image", "32", "--arch", "cube4"]


def _render(tmp_path, name, *extra):
    out = tmp_path / name
    assert main([*ARGS, "--fidelity", "cycle", "--out", str(out), "--quiet", *extra]) == 0
    stats = json.loads((out / "stats.json").read_text())
    return stats, np.load(out / "image.npy")


def test_two_workers_render_the_one_process_frame_bit_for_bit(tmp_path, capsys):
    one, one_image = _render(tmp_path, "one")
    assert (
        main([*ARGS, "--fidelity", "cycle", "--out", str(tmp_path / "two"), "--workers", "2"]) == 0
    )
    printed = capsys.readouterr().out
    two = json.loads((tmp_path / "two" / "stats.json").read_text())
    assert np.array_equal(np.load(tmp_path / "two" / "image.npy"), one_image)
    assert two["cycles"] == one["cycles"] and two["counters"] == one["counters"]
    assert one["split"] is None
    split = two["split"]
    assert split["workers"] == 2 and len(split["bands"]) == 2
    assert sum(b["samples"] for b in split["bands"]) == one["samples"]
    assert all(b["peak_rss_bytes"] > 0 and b["rows"] > 0 for b in split["bands"])
    assert "split across 2 workers in 2 bands" in printed
    assert main(["report", str(tmp_path / "two"), "--out", str(tmp_path / "report")]) == 0
    report = (tmp_path / "report" / "report.md").read_text()
    assert "### Split across workers" in report and "ran in 2 bands of rays on 2" in report


def test_one_bar_covers_every_band_and_a_killed_worker_s_band_is_rerun(tmp_path):
    from hwsim.core.cluster import local_client
    from hwsim.run.fidelity import resolve_arch
    from hwsim.run.frame_split import split_frame
    from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import load_volume
    from hwsim.volumes.parts import volume_parts
    from models.cycle import render_cycle
    from models.frame import frame_of

    scene = Scene(
        volume=VolumeSpec(phantom="head", params=(("size", 64),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=20, width=64, height=64, zoom=1.3),
        render=RenderSpec(mode="composite"),
    )
    arch = resolve_arch("cube4")
    whole = load_volume(scene.volume)
    reference = render_cycle(frame_of(scene, whole, resolve_transfer(scene.transfer, whole), arch))
    volume = volume_parts(scene.volume).volume()
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
    seen, killed = [], []
    with local_client(2) as client:

        def progress(done, total):
            seen.append((done, total))
            if done and not killed:
                holding = [w for w, keys in client.processing().items() if keys]
                pid = client.run(os.getpid, workers=holding[:1])[holding[0]]
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)

        result, info = split_frame(frame, client=client, progress=progress)
    assert killed, "no worker was killed mid-frame"
    np.testing.assert_array_equal(result.image, reference.image)
    assert result.cycles == reference.cycles and result.counters == reference.counters
    assert all(not b["host"].endswith(f":{killed[0]}") for b in info["bands"])
    totals = {t for _, t in seen}
    assert totals == {2 * frame.plan.n_steps}  # one bar: every band's steps
    done = [d for d, _ in seen]
    assert done == sorted(done) and done[-1] == 2 * frame.plan.n_steps


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--fidelity", "functional", "--workers", "2"], "--workers: the functional rung"),
        (["--fidelity", "cycle", "--workers", "0"], "--workers: 0 is out of range"),
        (["--fidelity", "cycle", "--bands", "2"], "--bands: cuts a frame split across workers"),
        (
            ["--fidelity", "cycle", "--workers", "2", "--arch", "volumepro500"],
            "volumepro500 renders a frame in one process",
        ),
        (
            ["--fidelity", "cycle", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
            "give a worker count or a scheduler, not both",
        ),
        (["--fidelity", "cycle", "--workers", "2", "--frames", "3"], "--workers: a turntable"),
        (
            ["--fidelity", "cycle", "--workers", "2", "--phantom", "ball:size=16"],
            "phantom 'ball' is generated whole",
        ),
    ],
    ids=["functional", "zero", "bands-alone", "volumepro", "both", "turntable", "ball"],
)
def test_what_cannot_be_split_is_refused_in_one_line(tmp_path, capsys, extra, message):
    assert main([*ARGS, "--out", str(tmp_path / "x"), "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_a_compressed_volume_is_refused_and_its_conversion_is_read_in_parts(tmp_path, capsys):
    import nrrd

    from hwsim.volumes import make_phantom

    data = make_phantom("head", size=16).data
    packed = tmp_path / "head.nrrd"
    nrrd.write(
        str(packed), data, {"encoding": "gzip", "spacings": [1.0, 1.0, 2.0]}, index_order="C"
    )
    args = [*ARGS[:1], "--volume", str(packed), "--image", "16", "--arch", "cube4", "--quiet"]
    assert main([*args, "--fidelity", "cycle", "--workers", "1", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err.strip()
    assert "encoding: gzip-encoded data cannot be read a part at a time" in err
    assert "hwsim convert" in err
    raw = tmp_path / "raw.nrrd"
    assert main(["convert", str(packed), str(raw)]) == 0
    assert "spacing (2.0, 1.0, 1.0)" in capsys.readouterr().out
    raw_args = [*ARGS[:1], "--volume", str(raw), "--image", "16", "--arch", "cube4", "--quiet"]
    split = [*raw_args, "--fidelity", "cycle", "--workers", "1", "--out", str(tmp_path / "b")]
    assert main(split) == 0
    assert main([*args, "--fidelity", "cycle", "--out", str(tmp_path / "c")]) == 0
    b, c = (json.loads((tmp_path / n / "stats.json").read_text()) for n in "bc")
    assert b["cycles"] == c["cycles"] and b["counters"] == c["counters"]
    image_b, image_c = (np.load(tmp_path / n / "image.npy") for n in "bc")
    assert np.array_equal(image_b, image_c)
    same = ("shape_zyx", "spacing_zyx", "dtype", "bits", "units", "value_range")
    assert {k: b["volume"][k] for k in same} == {k: c["volume"][k] for k in same}
