"""Environment variables (issue 33), the fuzz tier: hypothesis draws a value for each
``HWSIM_*`` variable; ``hwsim scenes`` (no work of its own, in process) accepts it, or
refuses it in one line naming the variable and its allowed range, exit status 2.
tests/test_env.py has the fixed cases and the checks that keep the list honest.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from fuzz_documents import FUZZ
from hypothesis import example, given
from hypothesis import strategies as st

from hwsim.cli.commands import main
from hwsim.core import env
from hwsim.core.errors import InputError

pytestmark = pytest.mark.fuzz

#: Printable text an environment can hold (no NUL, no lone surrogate).
TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), max_size=40)
ODD = ["inf", "-inf", "nan", "abc", "-1", "0", "1e400", "9" * 400, " ", "1.5", "0x10", "2G", "-2G"]
VALUES = st.one_of(TEXT, st.sampled_from(ODD), st.integers().map(str), st.floats().map(str))
#: Read through hwsim.core.env: what the parsers return for each variable.
KINDS = {"HWSIM_THREADS": int, "HWSIM_MAX_MEMORY": int, "HWSIM_MAX_SAMPLES": int,
         "HWSIM_DEBUG": bool, "HWSIM_RTL_BUILD": Path, "HWSIM_SHARED_DATA": Path}  # fmt: skip


@FUZZ
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
