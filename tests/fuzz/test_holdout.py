"""The hold-out set of issue 33 (tests/fuzz/holdout_cases.py), a bounded sample in CI:
the first two cases of each class; ``HOLDOUT_ALL=1`` runs every case.  Each must end in
one ``hwsim: error:`` line with exit 2 (or a correct result where the input is odd but
valid), no traceback, and every input file unchanged."""

from __future__ import annotations

import os

import pytest
from holdout_cases import CASES, run_case

pytestmark = pytest.mark.fuzz


def _sample() -> list:
    if os.environ.get("HOLDOUT_ALL"):
        return CASES
    taken: dict[str, int] = {}
    chosen = []
    for case in CASES:
        if taken.get(case.kind, 0) < 2:
            taken[case.kind] = taken.get(case.kind, 0) + 1
            chosen.append(case)
    return chosen


@pytest.mark.parametrize("case", _sample(), ids=lambda c: c.name)
def test_holdout_case(case, tmp_path):
    passed, why = run_case(case, tmp_path)
    assert passed, why


def test_the_hold_out_is_large_and_covers_every_class():
    kinds = {c.kind.split(":")[0] for c in CASES}
    assert len(CASES) >= 40 and len({c.name for c in CASES}) == len(CASES)
    assert {"arch", "scene", "technology", "sweep", "transfer", "report", "os", "env",
            "formats", "inputs as outputs"} <= kinds  # fmt: skip
