"""Files named inside other files are inputs too (issue 33, by construction).

Every reader calls :func:`hwsim.core.paths.input_file` before it opens a file, and the
command line records those calls (:func:`hwsim.core.paths.recording_reads`); each
command loads its scene, machines and technologies before it plans its outputs, so a
technology an architecture file names, the ``base`` of a technology and a table a scene
names are refused as outputs exactly like the files given on the command line, before
any frame.  The report plans its plot PNGs too, and :func:`hwsim.api.trade` plans as the
command line does.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from cli_errors import one_line_error

import hwsim
import hwsim.run.fidelity
from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.core.paths import atomic_write, recording_reads, repo_root

pytestmark = pytest.mark.system

SCENE = """schema = 1
[volume]
phantom = "ball"
params = { size = 8 }
[view]
width = 8
height = 8
"""


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def no_frame(monkeypatch):
    def tripwire(*args, **kwargs):
        raise AssertionError("work started before the outputs were checked")

    monkeypatch.setattr(hwsim.run.fidelity, "render", tripwire)
    monkeypatch.setattr("hwsim.studies.trade.ladder.ladder_trade", tripwire)
    monkeypatch.setattr("hwsim.studies.figures_tables.measure_figures", tripwire)


def _technology(folder: Path, name: str = "tech.toml", base: str | None = None) -> Path:
    path = folder / name
    text = (repo_root() / "hwsim/energy/technologies/cmos45.toml").read_text()
    if base is not None:  # a derived node: cmos250's file, its base pointed at ours
        text = (repo_root() / "hwsim/energy/technologies/cmos250.toml").read_text()
        text = text.replace('base = "cmos45"', f'base = "{base}"')
        assert f'base = "{base}"' in text
    path.write_text(text)
    return path


def _arch_naming(folder: Path, technology: Path) -> Path:
    text = (repo_root() / "models/machines/cube4/cube4.toml").read_text()
    text = text.replace('technology = "cmos350"', f'technology = "{technology}"')
    assert str(technology) in text
    path = folder / "arch.toml"
    path.write_text(text)
    return path


def _refused(capsys, argv: list[str], kept: Path, *fragments: str) -> None:
    before = _digest(kept)
    assert main(argv) == 2
    one_line_error(capsys, "an output never replaces an input", *fragments)
    assert _digest(kept) == before


def test_a_technology_named_in_an_arch_file_is_an_input(tmp_path, capsys, no_frame):
    tech = _technology(tmp_path)
    arch = _arch_naming(tmp_path, tech)
    argv = ["render", "--arch", str(arch), "--fidelity", "cycle", "--out", str(tmp_path / "o")]
    _refused(capsys, [*argv, "--trace", str(tech), "--quiet"], tech, str(tech))


def test_a_base_technology_is_an_input(tmp_path, capsys, no_frame):
    base = _technology(tmp_path, "base.toml")
    derived = _technology(tmp_path, "derived.toml", base=str(base))
    argv = ["render", "--arch", "cube4", "--fidelity", "cycle", "--technology", str(derived)]
    argv += ["--out", str(tmp_path / "o"), "--trace", str(base), "--quiet"]
    _refused(capsys, argv, base, str(base))


def test_a_table_named_in_a_scene_is_an_input(tmp_path, capsys, no_frame):
    """The scene's transfer table lies where the render writes image.npy."""
    out = tmp_path / "out"
    out.mkdir()
    table = out / "image.npy"
    np.save(table, np.array([[0, 0, 0, 0, 0], [255, 1, 1, 1, 1]], dtype=float)[:, :4])
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE + '[transfer]\ntable = "out/image.npy"\n')
    _refused(capsys, ["render", str(scene), "--out", str(out), "--quiet"], table, "transfer.table")


def test_an_arch_technology_is_an_input_of_figures(tmp_path, capsys, no_frame):
    out = tmp_path / "out"
    out.mkdir()
    tech = _technology(out, "figures.md")  # where figures writes its table
    arch = _arch_naming(tmp_path, tech)
    _refused(capsys, ["figures", "--arch", str(arch), "--out", str(out), "--quiet"], tech)


def test_api_trade_plans_as_the_command_line(tmp_path, no_frame):
    """hwsim.trade(out=...) refuses an output that is an input, before any render."""
    out = tmp_path / "out"
    out.mkdir()
    tech = _technology(out, "trade.md")
    arch = _arch_naming(tmp_path, tech)
    before = _digest(tech)
    with pytest.raises(InputError, match="never replaces an input"):
        hwsim.trade(archs=[str(arch)], out=out)
    assert _digest(tech) == before
    volume = out / "trade.json"  # not a .npy, but trade.json is what it would write
    volume.write_bytes(b"x")
    with pytest.raises(InputError, match="never replaces an input"):
        hwsim.trade(volumes=[str(volume)], out=out)


def test_a_write_never_replaces_a_file_read(tmp_path):
    """The write-time guard: a file read in the command is never renamed over."""
    src = tmp_path / "scene.toml"
    src.write_text(SCENE)
    with recording_reads():
        hwsim.load_scene(str(src))
        with pytest.raises(InputError, match="never replaces an input"), atomic_write(src) as tmp:
            tmp.write_text("replaced")
    assert src.read_text() == SCENE
    with atomic_write(src) as tmp:  # outside a command's record: an ordinary write
        tmp.write_text("new")
    assert src.read_text() == "new"


def test_report_plots_are_planned(tmp_path, capsys):
    """A folder where the report would draw a run's plot: refused before report.md."""
    run = tmp_path / "run"
    assert main(["render", "--phantom", "ball:size=8", "--image", "8", "--fidelity",
                 "functional", "--out", str(run), "--quiet"]) == 0  # fmt: skip
    out = tmp_path / "report"
    (out / "run1-images.png").mkdir(parents=True)
    capsys.readouterr()
    assert main(["report", str(run), "--out", str(out), "--quiet"]) == 2
    one_line_error(capsys, "run1-images.png", "is a folder")
    assert not (out / "report.md").exists()


def test_report_plot_names_are_the_planned_ones(tmp_path):
    """Every PNG a report draws is one report_paths listed."""
    from hwsim.report.report import report_paths, write_report

    run = tmp_path / "run"
    assert main(["render", "--phantom", "ball:size=8", "--image", "8", "--fidelity",
                 "cycle", "--arch", "cube4", "--out", str(run), "--quiet"]) == 0  # fmt: skip
    out = tmp_path / "report"
    write_report([run], out)
    planned = set(report_paths(out, [run]).values())
    drawn = set(out.glob("*.png"))
    assert drawn and drawn <= planned, drawn - planned


def test_a_volume_on_a_sweep_axis_is_read_as_an_input(tmp_path, capsys):
    """A sweep's volume axis is checked by input_file when the sweep loads (it was only
    checked to exist): a named pipe there is refused in one line before any run, and a
    real volume is recorded as read."""
    import os

    fifo = tmp_path / "pipe.nrrd"
    os.mkfifo(fifo)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('schema = 1\n[sweep]\nvolume = ["pipe.nrrd"]\nfidelity = ["golden"]\n'
                     "image = [8]\n")  # fmt: skip
    db = tmp_path / "runs.db"
    assert main(["sweep", str(sweep), "--db", str(db), "--quiet"]) == 2
    one_line_error(capsys, str(sweep), "sweep.volume[0]", "named pipe")
    assert not db.exists()
    volume = tmp_path / "ball.npy"
    np.save(volume, np.zeros((8, 8, 8), np.uint8))
    sweep.write_text(sweep.read_text().replace("pipe.nrrd", "ball.npy"))
    from hwsim.core.paths import reads
    from hwsim.studies.sweep.spec import load_sweep

    with recording_reads():
        load_sweep(sweep)
        read = {Path(path).resolve() for _, path in reads()}
    assert volume.resolve() in read
