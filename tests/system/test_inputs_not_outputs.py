"""Inputs are never outputs; outputs are atomic; nothing computed is lost (issue 33).

Every command plans all the paths it will write before any work
(:func:`hwsim.core.paths.plan_outputs`): an output that is one of the command's inputs,
or a folder where a file goes (or a file where a folder goes), is one line and exit 2,
the input untouched.  Files are written to a temporary name and renamed, so a failed
write leaves the earlier result in place, and one failed file does not lose the others.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from cli_errors import one_line_error, run_cli
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hwsim.run.fidelity
import hwsim.run.output
import hwsim.run.turntable
from hwsim.cli.commands import main
from hwsim.core.paths import atomic_write, plan_outputs, repo_root

pytestmark = pytest.mark.system

SCENE = """schema = 1
[volume]
phantom = "ball"
params = { size = 8 }
[view]
width = 8
height = 8
"""
SWEEP = '[sweep]\nphantom = ["ball:size=8"]\nfidelity = ["functional"]\n'


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _inputs(folder: Path) -> dict[str, Path]:
    """One file of each kind a command reads, in ``folder``."""
    paths = {
        "scene": folder / "scene.toml",
        "volume": folder / "vol.npy",
        "arch": folder / "arch.toml",
        "sweep": folder / "sweep.toml",
        "stats": folder / "run" / "stats.json",
    }
    paths["stats"].parent.mkdir()
    paths["scene"].write_text(SCENE)
    np.save(paths["volume"], np.arange(512, dtype=np.uint8).reshape(8, 8, 8))
    shutil.copy(repo_root() / "models/machines/cube4/cube4.toml", paths["arch"])
    paths["sweep"].write_text(SWEEP)
    paths["stats"].write_text(json.dumps({"schema": 1}))
    return paths


RENDER_OUTPUTS = {"--out": "dir", "--trace": "file"}
#: command -> (argv with {input} placeholders, its output flags and their kinds).
#: Every output flag of every command that has inputs; each output is pointed at each
#: input (or at a path of the wrong kind) by the property below.
COMMANDS = {
    "render-scene": (["render", "{scene}", "--fidelity", "cycle"], RENDER_OUTPUTS),
    "render-volume": (["render", "--volume", "{volume}"], RENDER_OUTPUTS),
    "render-arch": (["render", "--arch", "{arch}", "--fidelity", "cycle"], RENDER_OUTPUTS),
    "turntable": (["render", "{scene}", "--frames", "3"], {"--out": "dir"}),
    "convert": (["convert", "{volume}"], {"OUT": "file"}),
    "sweep": (["sweep", "{sweep}"], {"--db": "file", "--out": "dir"}),
    "report": (["report", "{run}"], {"--out": "dir"}),
    "trade": (["trade", "--volume", "{volume}", "--arch", "{arch}"], {"--out": "dir"}),
    "figures": (["figures", "--arch", "{arch}"], {"--out": "dir"}),
    "bench": (["bench", "--arch", "{arch}"], {"--out": "dir"}),
}  # fmt: skip


@pytest.fixture
def no_work(monkeypatch):
    """Fail if any frame, turntable frame or sweep starts."""

    def tripwire(*args, **kwargs):
        raise AssertionError("work started before the outputs were checked")

    monkeypatch.setattr(hwsim.run.fidelity, "render", tripwire)
    monkeypatch.setattr(hwsim.run.turntable, "render", tripwire)
    monkeypatch.setattr("hwsim.studies.sweep.runner.run_sweep", tripwire)
    monkeypatch.setattr("hwsim.studies.bench.run_bench", tripwire)
    monkeypatch.setattr("hwsim.studies.figures_tables.measure_figures", tripwire)
    monkeypatch.setattr("hwsim.studies.trade.ladder.ladder_trade", tripwire)


def _argv(command: str, paths: dict[str, Path], flag: str, target: Path) -> list[str]:
    template, _ = COMMANDS[command]
    names = {**{k: str(v) for k, v in paths.items()}, "run": str(paths["stats"].parent)}
    argv = [a.format(**names) for a in template]
    out = target.parent / "out-elsewhere"
    if flag == "OUT":
        return [*argv, str(target)]
    if command == "convert":
        argv.append(str(out / "v.npy"))
    if flag != "--out" and "--out" in COMMANDS[command][1]:
        argv += ["--out", str(out)]
    return [*argv, flag, str(target), "--quiet"]


def _run_refused(capsys, argv: list[str], paths: dict[str, Path]) -> str:
    before = {name: _digest(p) for name, p in paths.items()}
    assert main(argv) == 2
    err = one_line_error(capsys)
    assert {name: _digest(p) for name, p in paths.items()} == before, "an input changed"
    return err


OUTPUT_FLAGS = [(c, f) for c, (_, flags) in COMMANDS.items() for f in flags]


def _inputs_of(command: str) -> list[str]:
    """The input files of ``command``'s template (a report reads its run's stats.json)."""
    names = re.findall(r"\{(\w+)\}", " ".join(COMMANDS[command][0]))
    return ["stats" if n == "run" else n for n in names]


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    pair=st.sampled_from(OUTPUT_FLAGS),
    how=st.sampled_from(["same", "symlink", "hardlink", "wrong-kind"]),
    data=st.data(),
)
def test_no_output_is_an_input_or_the_wrong_kind(capsys, no_work, pair, how, data):
    """Any output flag of any command pointed at any of its inputs (directly, through a
    symbolic or a hard link) or at a path of the wrong kind: exit 2, one line naming the
    flag, every input unchanged, no work started."""
    command, flag = pair
    which = data.draw(st.sampled_from(_inputs_of(command)), label="input")
    kind = COMMANDS[command][1][flag]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = _inputs(folder)
        target = paths[which]
        link = folder / f"link{target.suffix}"  # convert reads the type from OUT's suffix
        if how == "symlink":
            link.symlink_to(target)
            target = link
        elif how == "hardlink":
            os.link(target, link)
            target = link
        elif how == "wrong-kind":  # a folder where a file goes, a file where a folder goes
            target = folder / "wrong.npy"
            target.mkdir() if kind == "file" else target.write_text("a file")
        argv = _argv(command, paths, flag, target)
        err = _run_refused(capsys, argv, paths)
        assert flag in err


def test_volume_inside_out_under_the_name_of_an_output(tmp_path, capsys, no_work):
    """The issue's example: ``--volume OUT/image.npy --out OUT``."""
    (tmp_path / "out").mkdir()
    volume = tmp_path / "out" / "image.npy"
    np.save(volume, np.ones((8, 8, 8), np.uint8))
    argv = ["render", "--volume", str(volume), "--out", str(tmp_path / "out"), "--quiet"]
    err = _run_refused(capsys, argv, {"volume": volume})
    assert "image.npy: --out: is the input" in err and "(--volume)" in err


def test_an_input_in_a_dicom_like_folder_counts_as_every_file_in_it(tmp_path, capsys):
    series = tmp_path / "series"
    series.mkdir()
    (series / "slice1.dcm").write_bytes(b"x")
    with pytest.raises(Exception, match="is inside the input"):
        plan_outputs([("--volume", series)], [("--trace", series / "wave.vcd", "file")])
    plan_outputs([("--volume", series)], [("--trace", tmp_path / "wave.vcd", "file")])


@pytest.mark.parametrize("blocker", ["frames", "turntable.gif", "frames/frame_0001.png"])
def test_a_turntable_with_a_wrong_kind_output_fails_before_its_first_frame(
    tmp_path, capsys, no_work, blocker
):
    """``frames/`` a file, ``turntable.gif`` or one frame's PNG a folder: refused before
    any frame is rendered (the renderers are tripwires)."""
    out = tmp_path / "tt"
    (out / "frames").mkdir(parents=True)
    if blocker == "frames":
        (out / "frames").rmdir()
        (out / "frames").write_text("a file")
    else:
        (out / blocker).mkdir()
    argv = ["render", "--phantom", "ball:size=8", "--image", "8", "--frames", "3"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 2
    one_line_error(capsys, blocker)


def _render(out: Path, view: str) -> int:
    argv = ["render", "--phantom", "ball:size=8", "--image", "8", "--view", view]
    return main([*argv, "--out", str(out), "--quiet"])


def test_a_failed_png_write_keeps_the_earlier_png_and_saves_the_rest(tmp_path, capsys, monkeypatch):
    out = tmp_path / "r"
    assert _render(out, "30,15") == 0
    earlier = {p.name: p.read_bytes() for p in out.iterdir()}

    def full_disk(rgb, path):
        with atomic_write(path) as tmp:
            tmp.write_bytes(b"half a png")
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(hwsim.run.output, "_save_png", full_disk)
    assert _render(out, "60,10") == 2
    err = one_line_error(capsys, "image.png", "No space left on device", "saved")
    assert "image.npy" in err and "stats.json" in err
    assert (out / "image.png").read_bytes() == earlier["image.png"]  # the earlier result
    stats = json.loads((out / "stats.json").read_text())
    assert stats["scene"]["view"]["azimuth"] == 60.0  # the new frame's numbers were kept
    assert (out / "image.npy").read_bytes() != earlier["image.npy"]
    assert sorted(p.name for p in out.iterdir()) == sorted(earlier)  # no temporary left


def test_an_interrupted_write_leaves_the_earlier_file(tmp_path, monkeypatch):
    """A write that dies half way (here np.save) never replaces the file it targets."""
    out = tmp_path / "r"
    assert _render(out, "30,15") == 0
    earlier = (out / "image.npy").read_bytes()

    def dies(fh, *args, **kwargs):
        fh.write(b"\x93NUMPY half")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "save", dies)
    assert _render(out, "60,10") == 130
    assert (out / "image.npy").read_bytes() == earlier
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_an_unknown_arch_technology_is_refused_before_the_frame(tmp_path, capsys, monkeypatch):
    """Named by the architecture file and its key, not by --technology (not given)."""

    def tripwire(*args, **kwargs):
        raise AssertionError("the frame started before the technology was checked")

    monkeypatch.setattr(hwsim.run.fidelity, "choose_execution", tripwire)
    arch = tmp_path / "arch.toml"
    text = (repo_root() / "models/machines/cube4/cube4.toml").read_text()
    arch.write_text(re.sub(r'(?m)^technology = "\w+"', 'technology = "cmos999"', text))
    argv = ["render", "--phantom", "ball:size=8", "--image", "8", "--fidelity", "cycle"]
    assert main([*argv, "--arch", str(arch), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = one_line_error(capsys, str(arch), "silicon.technology", "cmos999")
    assert "--technology" not in err


@pytest.mark.parametrize(
    "argv",
    [
        ["render", "scene.toml", "--fidelity", "cycle", "--trace", "scene.toml", "--out", "o"],
        ["render", "--volume", "o/image.npy", "--out", "o", "--quiet"],
        ["convert", "vol.npy", "vol.npy"],
        ["convert", "vol.npy", "./o/../vol.npy"],
        ["sweep", "sweep.toml", "--db", "sweep.toml", "--quiet"],
        ["report", "o", "--out", "o/stats.json", "--quiet"],
        ["render", "scene.toml", "--frames", "2", "--out", "tt"],
    ],
    ids=["trace-is-scene", "volume-in-out", "convert", "convert-dotted", "db", "report", "gif"],
)
def test_the_issue_examples_from_the_command_line(tmp_path, argv):
    (tmp_path / "scene.toml").write_text(SCENE)
    (tmp_path / "sweep.toml").write_text(SWEEP)
    (tmp_path / "o").mkdir()
    np.save(tmp_path / "vol.npy", np.ones((8, 8, 8), np.uint8))
    np.save(tmp_path / "o" / "image.npy", np.ones((8, 8, 8), np.uint8))
    (tmp_path / "o" / "stats.json").write_text("{}")
    (tmp_path / "tt" / "turntable.gif").mkdir(parents=True)
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    before = {p: _digest(p) for p in files}
    done = run_cli(*argv, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("hwsim: error: ")
    assert "output" in done.stderr or "folder" in done.stderr, done.stderr  # not a usage error
    assert {p: _digest(p) for p in files} == before
    assert not (tmp_path / "tt" / "frames").exists()  # the turntable rendered nothing
