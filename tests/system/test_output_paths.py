"""Every output path is checked and created before any work starts (issue 14).

An unwritable ``--out``, ``--trace`` or ``--db`` is one line on stderr and exit 2 before
the scene is rendered; the renderers are replaced by a tripwire to prove no work ran.
"""

from __future__ import annotations

import pytest
from cli_errors import one_line_error

import hwsim.run.fidelity
from hwsim.cli.commands import main

pytestmark = pytest.mark.system


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if any render starts."""

    def tripwire(*args, **kwargs):
        raise AssertionError("work started before the outputs were checked")

    monkeypatch.setattr(hwsim.run.fidelity, "render", tripwire)


@pytest.fixture
def blocker(tmp_path):
    """A plain file standing where a folder would have to be created."""
    path = tmp_path / "blocker"
    path.write_text("not a folder")
    return path


def test_trace_inside_an_out_folder_that_does_not_exist_yet(tmp_path):
    """The README's line: the VCD goes into the --out folder the render creates."""
    out = tmp_path / "c4"
    argv = ["render", "--fidelity", "cycle", "--arch", "cube4", "--phantom", "ball:size=8"]
    argv += ["--image", "8", "--out", str(out), "--trace", str(out / "wave.vcd"), "--quiet"]
    assert main(argv) == 0
    assert (out / "wave.vcd").read_text().startswith("$")  # a VCD header
    assert (out / "stats.json").is_file()


@pytest.mark.parametrize(
    ("flag", "child", "message"),
    [
        ("--out", "blocker/sub", "cannot create output folder"),
        ("--out", "blocker", "exists and is not a folder"),
        ("--trace", "blocker/wave.vcd", "exists and is not a folder"),
        ("--trace", ".", "is a folder"),
    ],
)
def test_unwritable_render_outputs_are_refused_before_rendering(
    tmp_path, blocker, capsys, no_work, flag, child, message
):
    argv = ["render", "--phantom", "ball:size=8", "--out", str(tmp_path / "ok"), "--quiet"]
    argv += [flag, str(tmp_path / child)]
    assert main(argv) == 2
    one_line_error(capsys, flag, message)


@pytest.mark.parametrize(
    "argv",
    [
        ["trade", "--out", "{b}/t", "--quiet"],
        ["trade", "--widths", "--out", "{b}/t", "--quiet"],
        ["figures", "--out", "{b}/f", "--quiet"],
        ["report", "{tmp}", "--out", "{b}/r", "--quiet"],
        ["bench", "--out", "{b}/b", "--quiet"],
        ["rtl", "build", "interp", "--out", "{b}/v", "--quiet"],
    ],
    ids=["trade", "trade-widths", "figures", "report", "bench", "rtl-build"],
)
def test_every_command_checks_its_out_folder_first(tmp_path, blocker, capsys, no_work, argv):
    argv = [a.format(b=blocker, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    one_line_error(capsys, "--out", str(blocker))


def test_sweep_checks_db_and_out_before_starting_workers(tmp_path, blocker, capsys):
    sweep = tmp_path / "s.toml"
    sweep.write_text('[sweep]\narch = ["cube4"]\nfidelity = ["functional"]\nphantom = ["ball"]\n')
    assert main(["sweep", str(sweep), "--db", str(blocker / "runs.db"), "--quiet"]) == 2
    one_line_error(capsys, "--db", str(blocker))
    assert main(["sweep", str(sweep), "--out", str(blocker / "o"), "--quiet"]) == 2
    one_line_error(capsys, "--out")
    assert not (tmp_path / "runs.db").exists()


def test_default_out_says_it_replaced_a_render(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["render", "--phantom", "ball:size=8", "--image", "8"]
    assert main(argv) == 0
    first = capsys.readouterr().out
    assert "out/render/image.png" in first and "replaced" not in first
    assert main(argv) == 0
    assert "no --out given: replaced the previous render there" in capsys.readouterr().out
