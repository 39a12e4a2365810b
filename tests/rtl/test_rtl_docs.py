"""docs/rtl.md names every payload field of every unit and each unit's LATENCY."""

import re
from pathlib import Path

import pytest
from stream_bench import leaves
from unit_cases import UNITS, make_case

pytestmark = pytest.mark.rtl
DOC = (Path(__file__).resolve().parents[2] / "docs" / "rtl.md").read_text()


@pytest.mark.parametrize("unit", UNITS)
def test_rtl_doc_row_names_every_field_and_the_latency(unit):
    case = make_case(unit)
    (row,) = [line for line in DOC.splitlines() if line.startswith(f"| `{unit}` |")]
    for layout in (case.in_layout, case.out_layout, case.load_layout):
        for key in {leaf.key for leaf in leaves(layout)} if layout is not None else ():
            assert re.search(rf"`{key}(\[\d\])?`", row), (unit, key)
    assert row.rstrip(" |").endswith(f"| {case.latency}")
