"""Environment variables (issue 33): every ``HWSIM_*`` value is checked at the start of a
command like a flag: accepted, or one line naming the variable and its allowed range and
exit status 2, before any work (a sweep's workers start only after the check).

The command run is ``hwsim scenes`` (no work of its own), in process; hypothesis draws
the values.  Two static checks keep the list honest: docs/cli.md has a row for every
variable, and the code reads no ``HWSIM_*`` variable that :data:`VARIABLES` lacks.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from hwsim.cli.commands import main
from hwsim.core import env
from hwsim.core.errors import InputError

REPO = Path(__file__).resolve().parents[1]
#: Printable text an environment can hold (no NUL, no lone surrogate).
TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), max_size=40)
ODD = ["inf", "-inf", "nan", "abc", "-1", "0", "1e400", "9" * 400, " ", "1.5", "0x10", "2G", "-2G"]
VALUES = st.one_of(TEXT, st.sampled_from(ODD), st.integers().map(str), st.floats().map(str))
#: Read through hwsim.core.env: what the parsers return for each variable.
KINDS = {"HWSIM_THREADS": int, "HWSIM_MAX_MEMORY": int, "HWSIM_MAX_SAMPLES": int,
         "HWSIM_DEBUG": bool, "HWSIM_RTL_BUILD": Path, "HWSIM_SHARED_DATA": Path}  # fmt: skip


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(name=st.sampled_from(sorted(env.VARIABLES)), text=VALUES)
@example(name="HWSIM_MAX_SAMPLES", text="inf")
@example(name="HWSIM_THREADS", text="abc")
@example(name="HWSIM_THREADS", text="-3")
@example(name="HWSIM_THREADS", text="100000")
@example(name="HWSIM_MAX_MEMORY", text="9" * 400)
def test_a_value_is_accepted_or_refused_in_one_line(monkeypatch, capsys, name, text):
    with monkeypatch.context() as patch:  # one example's value, not the earlier ones'
        patch.setenv(name, text)
        _accepted_or_refused(name, *_run_scenes(capsys))


def _run_scenes(capsys) -> tuple[int, str]:
    status = main(["scenes"])
    return status, capsys.readouterr().err


def _accepted_or_refused(name: str, status: int, err: str) -> None:
    if status == 0:
        value = env.value(name)  # what the library reads: of its kind, in range
        assert value is None or isinstance(value, KINDS[name]), value
        if name == "HWSIM_THREADS" and value is not None:
            assert 1 <= value <= env.MAX_THREADS
        return
    assert status == 2, err
    assert err.count("\n") == 1 and err.startswith(f"hwsim: error: {name}: "), err
    assert "(allowed: " in err, err
    with pytest.raises(InputError):
        env.value(name)


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
