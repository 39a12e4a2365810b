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
from hypothesis import given, settings
from hypothesis import strategies as st

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


#: (exponent of L / L0, exponent of V / V0) of each table (docs/energy.md).
RULES = {"energy": (1, 2), "area": (2, 0), "timing": (1, 0)}
OWN = {"dram_read_bit_pj", "dram_activate_pj", "dram_refresh_pj"}


@settings(max_examples=30, deadline=None)
@given(node=st.floats(1.0, 10000.0), vdd=st.floats(0.1, 15.0, exclude_min=True))
def test_a_derived_file_scales_its_base_by_the_stated_rules(tmp_path_factory, node, vdd):
    """Any node and supply in range: what a derived file leaves out is its base's value
    times (L/L0)^a (V/V0)^b, a gate level in FO4 is the base's, its own keys its own."""
    base = load_technology("cmos45")
    own = "".join(f'{k} = {{ value = 1.5, tag = "V", source = "mine" }}\n' for k in sorted(OWN))
    path = tmp_path_factory.mktemp("tech") / "mine.toml"
    path.write_text(
        f'schema = 1\n[technology]\nname = "mine"\nnode_nm = {node!r}\nvdd = {vdd!r}\n'
        f'base = "cmos45"\n[energy]\n{own}[leakage]\n'
        'w_per_mm2 = { value = 0.5, tag = "I", source = "mine" }\n'
    )
    tech = load_technology(str(path))
    for table, (le, ve) in RULES.items():
        factor = (node / base.node_nm) ** le * (vdd / base.vdd) ** ve
        for key, value in base.values[table].items():
            want = 1.5 if key in OWN else value if key == "gate_level_fo4" else value * factor
            assert tech.values[table][key] == pytest.approx(want, rel=1e-12), key
    assert tech.values["leakage"] == {"w_per_mm2": 0.5} and tech.base == "cmos45"


if __name__ == "__main__":  # rewrite the snapshot from the current loader
    techs = {n: technology_values(load_technology(n)) for n in sorted(builtin_technologies())}
    SNAPSHOT.write_text(json.dumps(techs, indent=1, sort_keys=True) + "\n")
