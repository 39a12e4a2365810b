"""Outputs record paths relative to the run folder, the repository or as typed, never as
the machine's absolute paths (issue 32; ``hwsim.core.paths.display_path``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from hwsim.cli.commands import main
from hwsim.core.paths import display_path, display_text, locate, repo_root

pytestmark = pytest.mark.system

REPO = Path(__file__).resolve().parents[2]


def strings(value):
    """Every string in a JSON value."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from strings(v)
    elif isinstance(value, list):
        for v in value:
            yield from strings(v)


def absolute(value, *folders: Path) -> list[str]:
    """The strings of ``value`` that are absolute paths or name one of ``folders``."""
    return [s for s in strings(value) if os.path.isabs(s) or any(str(f) in s for f in folders)]


@pytest.fixture
def volume_here(tmp_path, monkeypatch):
    """A small volume file in a working folder outside the repository."""
    monkeypatch.chdir(tmp_path)
    ramp = np.arange(8**3, dtype=np.uint8).reshape(8, 8, 8)
    ramp.tofile(tmp_path / "v.raw")
    np.save(tmp_path / "v.npy", ramp)
    return tmp_path


def test_a_relative_volume_is_recorded_as_typed_and_the_report_reads_it(volume_here):
    argv = ["render", "--volume", "v.raw", "--shape", "8,8,8", "--dtype", "uint8"]
    assert main([*argv, "--image", "8", "--out", "run", "--quiet"]) == 0
    stats = json.loads((volume_here / "run" / "stats.json").read_text())
    assert stats["scene"]["volume"]["path"] == "v.raw"
    assert stats["volume"]["source"] == "v.raw"
    assert absolute(stats, volume_here, REPO) == []

    assert main(["report", "run", "--out", "rep", "--quiet"]) == 0
    md = (volume_here / "rep" / "report.md").read_text()
    assert "from benchmarks/results/published-figures/figures.json, measured" in md
    assert str(volume_here) not in md and str(REPO) not in md
    assert "reference unavailable" not in md  # the golden re-render found v.raw again


def test_a_sweep_row_records_no_absolute_path(volume_here):
    from hwsim.studies.sweep import load_sweep, run_key
    from hwsim.studies.sweep.runner import execute_run

    (volume_here / "s.toml").write_text('[sweep]\nvolume = ["v.npy"]\nimage = [8]\n')
    run = load_sweep(volume_here / "s.toml").runs[0]
    row = execute_run(run, run_key(run), str(volume_here / "runs"))
    assert row["status"] == "ok", row.get("error")
    assert row["volume"] == "v.npy" and row["run_dir"] == f"runs/{row['key'][:16]}"
    assert absolute(row, volume_here, REPO) == []
    written = json.loads((volume_here / row["run_dir"] / "stats.json").read_text())
    assert absolute(written, volume_here, REPO) == []


def test_display_path_prefers_the_run_folder_then_the_repository(tmp_path):
    root = repo_root()
    assert root == REPO
    run = tmp_path / "run"
    assert display_path(run / "image.png", run) == "image.png"
    assert display_path(REPO / "models" / "m.toml", run) == "models/m.toml"
    assert display_path(REPO.parent / "shared" / "data" / "ct.nrrd") == "../shared/data/ct.nrrd"
    assert display_path("my/own.raw") == "my/own.raw"  # relative: as typed
    outside = "/" + "nonexistent-hwsim-folder/v.raw"  # outside every folder: as given
    assert display_path(outside, run) == outside


def test_display_text_rewrites_the_paths_inside_a_message(tmp_path):
    message = f"{REPO / 'models/x.toml'}: limits: too big; {tmp_path / 'run/a.npy'} missing"
    shown = display_text(message, tmp_path / "run")
    assert shown == "models/x.toml: limits: too big; a.npy missing"
    url = "see https://example.org" + str(REPO) + "/x"
    assert display_text(url) == url  # not a path of this machine


def test_locate_finds_a_recorded_path_again(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "v.npy").write_bytes(b"")
    assert locate("v.npy", tmp_path / "run") == tmp_path / "run" / "v.npy"
    assert locate("pyproject.toml", tmp_path) == REPO / "pyproject.toml"
    assert locate("missing.npy", tmp_path) == Path("missing.npy")
