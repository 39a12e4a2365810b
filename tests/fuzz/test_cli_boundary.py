"""A handful of the fuzz tier's cases through the installed command, in a subprocess:
exit status 2, one line on stderr naming the file (or variable) and key, no traceback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from fuzz_documents import replaced, toml_dumps

pytestmark = pytest.mark.fuzz

REPO = Path(__file__).resolve().parents[2]
HWSIM = [sys.executable, "-m", "hwsim.cli.commands"]
RENDER = ["render", "--phantom", "head:size=8", "--image", "8", "--quiet"]


def _run(args: list[str], tmp_path: Path, **env: str) -> subprocess.CompletedProcess:
    environ = {k: v for k, v in os.environ.items() if not k.startswith("HWSIM_")}
    return subprocess.run(
        [*HWSIM, *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**environ, "PYTHONWARNINGS": "error", **env},
    )


def _one_line(result: subprocess.CompletedProcess, *names: str) -> None:
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    for name in names:
        assert name in lines[0], lines[0]


def _arch(tmp_path: Path, key: str, value) -> Path:
    doc = tomllib.loads((REPO / "models/machines/volumepro/volumepro500.toml").read_text())
    path = tmp_path / "bad-arch.toml"
    path.write_text(toml_dumps(replaced(doc, key, value)))
    return path


@pytest.mark.parametrize(("key", "value"), [("formats", 7), ("published", [1, 2])])
def test_arch_file_of_wrong_type(tmp_path, key, value):
    arch = _arch(tmp_path, key, value)
    out = tmp_path / "out"
    result = _run([*RENDER, "--arch", str(arch), "--out", str(out)], tmp_path)
    _one_line(result, "bad-arch.toml", f"{key}:")
    assert not (out / "stats.json").exists()  # refused before any work


def test_technology_with_zero_area(tmp_path):
    doc = tomllib.loads((REPO / "hwsim/energy/technologies/cmos45.toml").read_text())
    path = tmp_path / "zero.toml"
    path.write_text(toml_dumps(replaced(doc, "area.nand2_um2.value", 0)))
    args = [*RENDER, "--arch", "cube4", "--fidelity", "cycle", "--technology", str(path)]
    _one_line(_run([*args, "--out", "out"], tmp_path), "zero.toml", "area.nand2_um2.value")


def test_report_of_a_list(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "stats.json").write_text(json.dumps([1, 2]))
    (run / "image.npy").write_bytes(b"")
    _one_line(_run(["report", str(run), "--out", "rep"], tmp_path), "stats.json")


@pytest.mark.parametrize(("name", "text"), [("HWSIM_THREADS", "abc"), ("HWSIM_MAX_SAMPLES", "inf")])
def test_environment_value(tmp_path, name, text):
    result = _run([*RENDER, "--out", "out"], tmp_path, **{name: text})
    _one_line(result, name)
