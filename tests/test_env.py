"""Environment variables (issue 33): every ``HWSIM_*`` value is checked at the start of a
command like a flag: accepted, or one line naming the variable and its allowed range and
exit status 2, before any work (a sweep's workers start only after the check).

tests/fuzz/test_env.py draws values with hypothesis.  Two static checks here keep the
list honest: docs/cli.md has a row for every variable, and the code reads no
``HWSIM_*`` variable that :data:`VARIABLES` lacks.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.core import env

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("name", "text", "expected"),
    [
        ("HWSIM_THREADS", "3", 3),
        ("HWSIM_THREADS", "", None),
        ("HWSIM_MAX_SAMPLES", "1e6", 10**6),
        ("HWSIM_MAX_MEMORY", "2G", 2 << 30),
        ("HWSIM_DEBUG", "0", False),
        ("HWSIM_DEBUG", "yes", True),
    ],
)
def test_good_values_parse(monkeypatch, name, text, expected):
    monkeypatch.setenv(name, text)
    assert env.value(name) == expected


def test_a_folder_variable_naming_a_file_is_refused(monkeypatch, capsys, tmp_path):
    file = tmp_path / "file"
    file.write_text("")
    monkeypatch.setenv("HWSIM_RTL_BUILD", str(file))
    assert main(["scenes"]) == 2
    assert "HWSIM_RTL_BUILD" in capsys.readouterr().err


def test_a_sweep_refuses_a_bad_thread_count_before_its_workers_start(monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("HWSIM_THREADS", "abc")
    db = tmp_path / "runs.db"
    sweep = str(REPO / "docs" / "examples" / "sweep.toml")
    assert main(["sweep", sweep, "--workers", "1", "--db", str(db), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "HWSIM_THREADS" in err and "1 .. 256" in err, err
    assert not db.exists()


def test_docs_list_every_variable():
    text = (REPO / "docs" / "cli.md").read_text()
    rows = set(re.findall(r"^\| `(HWSIM_[A-Z_]+)` \|", text, re.MULTILINE))
    assert rows == set(env.VARIABLES)


def test_the_code_reads_no_other_variable():
    """Every ``HWSIM_*`` name the code mentions is declared (``HWSIM_PROGRESS`` is the RTL
    testbench's progress line, not a variable); none is read past hwsim.core.env."""
    named, reads = set(), []
    for folder in ("hwsim", "models", "rtl", "benchmarks"):
        for path in (REPO / folder).rglob("*.py"):
            text = path.read_text()
            named |= set(re.findall(r"\bHWSIM_[A-Z_]*[A-Z]\b", text))
            if path.name != "env.py" and re.search(r"(getenv|environ\.get)\(\s*\"HWSIM_", text):
                reads.append(str(path.relative_to(REPO)))
    assert named - {"HWSIM_PROGRESS"} <= set(env.VARIABLES)
    assert not reads
