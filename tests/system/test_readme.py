"""Every command of the README's "Using it" section runs and writes what it promises.

The first block runs on the run install (``HWSIM_RUN_VENV``, the venv ``.ci/run`` builds
with ``./dev run``; else this interpreter's venv), the RTL block on this venv, which has
the ``rtl`` extra.  Each command runs in a scratch folder laid out like a clone (``.venv``,
``docs`` and ``../shared`` are links), so the README's relative paths hold and its
outputs land in ``tmp_path``.  The only changes are :data:`SHRINK`: options appended to
commands that would take minutes at their defaults, each named here.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"

#: Options appended (argparse keeps the last) where a README command takes minutes.
SHRINK = {
    ("trade", "--widths"): ["--image", "32"],
    ("trade",): ["--image", "16", "--size", "16", "--rungs", "golden,functional"],
    ("figures",): ["--max-size", "128", "--rungs", "transaction"],
    ("bench",): [
        *("--size", "16", "--image", "16", "--repeats", "1", "--no-sweep", "--rtl-size", "16"),
        # golden_vs_vtk_first needs the bench extra (VTK): on the run install it is
        # skipped before any work, naming the extra, and the command still exits 0.
        *("--rows", "functional_vs_golden", "golden_vs_vtk_first"),
    ],
}

#: Files each command promises in its ``--out`` folder (docs/cli.md, README).
PROMISED = {
    "render": ["image.png", "image.npy", "stats.json"],
    "trade --widths": ["widths.csv", "widths.json", "widths.png"],
    "trade": ["trade.csv", "trade.json", "trade.png", "trade.md"],
    "figures": ["figures.json", "figures.csv", "figures.md"],
    "sweep": [],
    "report": ["report.md", "report.html"],
    "bench": ["bench.json"],
}


def readme_blocks() -> list[list[list[str]]]:
    """The ``sh`` blocks of "## Using it", each a list of commands split like a shell."""
    text = README.read_text()
    section = text.split("## Using it", 1)[1].split("\n## ", 1)[0]
    blocks = []
    for body in re.findall(r"```sh\n(.*?)```", section, flags=re.DOTALL):
        joined = body.replace("\\\n", " ")
        blocks.append([shlex.split(line, comments=True) for line in joined.splitlines()])
    return [[c for c in block if c] for block in blocks]


def _venv(env_name: str | None) -> Path:
    if env_name and os.environ.get(env_name):
        return Path(os.environ[env_name])
    return Path(sys.executable).parents[1]


def _shrunk(argv: list[str]) -> list[str]:
    for key in sorted(SHRINK, key=len, reverse=True):
        if argv[1] == key[0] and all(k in argv for k in key[1:]):
            return argv + SHRINK[key]
    return argv


def _value(argv: list[str], flag: str) -> str | None:
    return argv[argv.index(flag) + 1] if flag in argv else None


def _run_block(block: list[list[str]], venv: Path, root: Path) -> None:
    """Run ``block`` in a clone-like folder under ``root``; check exits and outputs."""
    clone = root / "hwsim"
    clone.mkdir()
    (clone / ".venv").symlink_to(venv)
    (clone / "docs").symlink_to(REPO / "docs")
    (root / "shared").symlink_to(REPO.parent / "shared")
    env = {**os.environ, "PYTHONWARNINGS": "ignore::DeprecationWarning"}
    for command in block:
        assert command[0] == ".venv/bin/hwsim", command
        argv = _shrunk(command)
        done = subprocess.run(argv, cwd=clone, env=env, capture_output=True, text=True)
        line = shlex.join(argv)
        assert done.returncode == 0, f"{line}\n{done.stderr[-2000:]}"
        assert "internal error" not in done.stderr, line
        if argv[1] in ("scenes", "archs"):
            assert done.stdout.count("\n") >= 3, line
        out = _value(argv, "--out")
        kind = "trade --widths" if "--widths" in argv else argv[1]
        for name in PROMISED.get(kind, []) if out else []:
            assert (clone / out / name).stat().st_size > 0, f"{line}: no {name}"
        for flag in ("--trace", "--db"):
            if _value(argv, flag):
                assert (clone / _value(argv, flag)).stat().st_size > 0, f"{line}: no {flag}"


@pytest.fixture
def shared_beside(shared_data):
    """The README reads ``../shared/data``: skip (fail under CI) without it."""
    return shared_data


def test_the_readme_has_its_blocks():
    blocks = readme_blocks()
    assert len(blocks) == 2 and len(blocks[0]) >= 15 and len(blocks[1]) >= 2
    assert all(any(c[1] == key[0] for c in blocks[0]) for key in SHRINK), "stale SHRINK key"


@pytest.mark.system
@pytest.mark.slow
def test_every_readme_command_runs_on_the_run_install(tmp_path, shared_beside):
    _run_block(readme_blocks()[0], _venv("HWSIM_RUN_VENV"), tmp_path)


@pytest.mark.system
@pytest.mark.cosim
def test_the_readme_rtl_commands_run_with_the_rtl_extra(tmp_path, shared_beside):
    _run_block(readme_blocks()[1], _venv(None), tmp_path)
