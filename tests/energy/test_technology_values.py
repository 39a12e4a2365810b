"""Every built-in technology loads to the values it had before its file kind moved onto a
msgspec model (issue 33): names, nodes, voltages, every table's value and its tag and
source, scaled ones included.

builtin_technologies.json was written by the Table-based loader (the commit that adds this
test); a change to a technology file or to the scaling rules updates it on purpose
(``python tests/energy/test_technology_values.py``).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from hwsim.energy.technology import Technology, builtin_technologies, load_technology

SNAPSHOT = Path(__file__).with_name("builtin_technologies.json")


def technology_values(tech: Technology) -> dict:
    """``tech`` as JSON types (ints and floats stay apart: ``1`` is not ``1.0``)."""
    return json.loads(json.dumps(dataclasses.asdict(tech)))


def test_the_snapshot_covers_every_builtin():
    assert sorted(json.loads(SNAPSHOT.read_text())) == sorted(builtin_technologies())


@pytest.mark.parametrize("name", sorted(builtin_technologies()))
def test_builtin_technology_loads_to_the_values_it_had(name):
    want = json.loads(SNAPSHOT.read_text())[name]
    got = technology_values(load_technology(name))
    assert got == want
    assert all(isinstance(v, float) for table in got["values"].values() for v in table.values())


if __name__ == "__main__":  # rewrite the snapshot from the current loader
    techs = {n: technology_values(load_technology(n)) for n in sorted(builtin_technologies())}
    SNAPSHOT.write_text(json.dumps(techs, indent=1, sort_keys=True) + "\n")
