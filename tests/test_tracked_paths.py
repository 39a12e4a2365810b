"""No tracked file holds an absolute path of the machine it was made on (issue 32).

Outputs record paths relative to the run folder or the repository
(``hwsim.core.paths.display_path``); committed results, docs and examples must too.  The
patterns are built from pieces so that this file does not match itself.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

_START = r"(?<![\w.~/-])"  # the start of a path, not the middle of a URL or a longer path
_USER = r"[^/\s\"'`]+/"
#: Absolute home, work and temporary folders (each spelled in pieces: see the docstring).
MACHINE_PATHS = re.compile(
    "|".join(
        [
            _START + "/" + "home/" + _USER,
            _START + "/" + "Users/" + _USER,
            _START + "/" + "root/",
            _START + "/" + "work/",
            _START + "/" + "tmp/" + "pytest-",
            _START + "/" + "private/var/" + "folders/",
            r"\b[A-Za-z]:[\\/]+" + "Users" + r"[\\/]",
        ]
    )
)


def machine_path_lines(name: str, text: str) -> list[str]:
    """``name:line: text`` for every line of ``text`` naming a machine's absolute path."""
    return [
        f"{name}:{n}: {line.strip()[:160]}"
        for n, line in enumerate(text.splitlines(), start=1)
        if MACHINE_PATHS.search(line)
    ]


def tracked_text_files() -> list[Path]:
    git = shutil.which("git")
    if git is None or not (REPO / ".git").exists():
        pytest.skip("not a git checkout: no list of tracked files")
    names = subprocess.run(
        [git, "ls-files", "-z"], cwd=REPO, capture_output=True, check=True
    ).stdout.split(b"\0")
    files = [REPO / n.decode() for n in names if n]
    return [f for f in files if f.is_file() and b"\0" not in f.read_bytes()[:8192]]


def test_no_tracked_file_names_a_machine_path():
    files = tracked_text_files()
    assert len(files) > 100  # the repository's files, not an empty listing
    found = []
    for path in files:
        text = path.read_bytes().decode("utf-8", errors="replace")
        found += machine_path_lines(path.relative_to(REPO).as_posix(), text)
    assert not found, "absolute machine paths in tracked files:\n" + "\n".join(found)


@pytest.mark.parametrize(
    "line",
    [
        "from " + "/" + "work/main/benchmarks/results/figures.json",
        '"note": "' + "/" + 'home/alice/hwsim/models/x.toml: bad"',
        "cd " + "/" + "Users/bob/src && hwsim render",
        "saved in " + "/" + "tmp/pytest-of-root/pytest-3/run0",
        "C:" + "\\" + "Users" + "\\" + "carol" + "\\" + "hwsim",
        "(" + "/" + "root/hwsim/stats.json)",
    ],
)
def test_machine_paths_are_found(line):
    assert machine_path_lines("f.md", f"ok\n{line}\n") == [f"f.md:2: {line}"]


@pytest.mark.parametrize(
    "line",
    [
        "../shared/data/ct_cranium.nrrd",
        "benchmarks/results/published-figures/figures.json",
        "https://example.org" + "/" + "work/paper.pdf",
        "docs" + "/" + "work/notes.md",
        "--out /tmp/run",
        "29.8 / 8 and samples/cycle",
    ],
)
def test_relative_paths_and_urls_pass(line):
    assert machine_path_lines("f.md", line) == []
