"""The example sweep (docs/examples/sweep.toml) and a sweep that lists every parameter
load to the axes and runs they had before the sweep file moved onto a msgspec model
(issue 33): the same values of the same types (``[16]`` is ``[16, 16]``, a clock in Hz a
float, a format width an int) in the same order.

example_sweeps.json was written by the Table-based loader (the commit that adds this
test); a change to the example or to the parameters updates it on purpose
(``python tests/sweep/test_sweep_values.py``).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hwsim.studies.sweep.spec import Sweep, load_sweep, parse_sweep

REPO = Path(__file__).resolve().parents[2]
SNAPSHOT = Path(__file__).with_name("example_sweeps.json")
EXAMPLE = "docs/examples/sweep.toml"
#: Every parameter a [sweep] table may list, ints where floats are read too.
EVERY_PARAMETER = {
    "schema": 1,
    "sweep": {
        "scene": ["head"],
        "phantom": ["ball:size=16"],
        "arch": ["cube4"],
        "fidelity": ["cycle"],
        "mode": ["mip"],
        "view": [[30, 10], [0.5, -90]],
        "image": [16, [24, 12]],
        "pipelines": [2],
        "clock_hz": [125e6, 100000000],
        "timing_only": [True],
        "technology": ["cmos45"],
        "formats": {"interp": {"weight_bits": [6, 8]}},
    },
}


def sweep_values(sweep: Sweep) -> dict:
    """The sweep's axes, size and every run's parameters and label, as JSON types."""
    runs = [[list(p) for p in run.params] for run in sweep.runs]
    labels = [run.label() for run in sweep.runs]
    data = {"axes": sweep.axes, "size": sweep.size, "runs": runs, "labels": labels}
    return json.loads(json.dumps(data))


def load(name: str) -> Sweep:
    if name == EXAMPLE:
        return load_sweep(REPO / EXAMPLE)
    return parse_sweep(EVERY_PARAMETER, source="s.toml", base_dir=REPO)


@pytest.mark.parametrize("name", [EXAMPLE, "every-parameter"])
def test_sweep_loads_to_the_values_it_had(name):
    want = json.loads(SNAPSHOT.read_text())[name]
    assert sweep_values(load(name)) == want


if __name__ == "__main__":  # rewrite the snapshot from the current loader
    data = {name: sweep_values(load(name)) for name in (EXAMPLE, "every-parameter")}
    SNAPSHOT.write_text(json.dumps(data, indent=1) + "\n")
