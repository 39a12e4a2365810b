"""The import layers of pyproject.toml's [tool.importlinter] hold (``lint-imports``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _lint_imports() -> str:
    found = Path(sys.executable).with_name("lint-imports")
    return str(found) if found.exists() else (shutil.which("lint-imports") or "lint-imports")


def test_every_import_contract_is_kept():
    done = subprocess.run([_lint_imports(), "--no-cache"], cwd=REPO, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "BROKEN" not in done.stdout and done.stdout.count("KEPT") >= 2


def test_a_layer_violation_is_caught(tmp_path):
    """The contract can fail: a copy of the tree whose golden renderer imports a unit model
    (a copy, so the real tree never holds the probe while other tests run)."""
    for package in ("hwsim", "models", "rtl", "benchmarks"):
        shutil.copytree(REPO / package, tmp_path / package, ignore=shutil.ignore_patterns("*.pyc"))
    shutil.copy(REPO / "pyproject.toml", tmp_path)
    probe = tmp_path / "hwsim" / "golden" / "_layer_probe.py"
    probe.write_text("import models.units  # deliberately breaks the golden contract\n")
    done = subprocess.run(
        [_lint_imports(), "--no-cache"],
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
        capture_output=True,
        text=True,
    )
    assert done.returncode != 0 and "hwsim.golden._layer_probe" in done.stdout, done.stdout
