"""``hwsim render --fidelity transaction``: stats.json, CSVs, the functional image."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hwsim.cli.commands import main

pytestmark = pytest.mark.system


def test_render_transaction_writes_cycles_counters_and_the_functional_image(tmp_path):
    args = ["render", "--phantom", "head:size=20", "--arch", "cube4", "--image", "20", "--quiet"]
    out = tmp_path / "t"
    assert main([*args, "--fidelity", "transaction", "--out", str(out)]) == 0
    stats = json.loads((out / "stats.json").read_text())
    assert stats["fidelity"] == "transaction" and stats["arch"] == "cube4"
    counters = stats["counters"]
    assert stats["cycles"] == counters["frame.cycles"] > 0
    assert counters["transaction.events"] > 0 and counters["pixel_bus.pixels"] > 0
    assert (out / "throughput.csv").is_file() and "pixel_bus" in (out / "memory.csv").read_text()
    assert main([*args, "--fidelity", "cycle", "--out", str(tmp_path / "c")]) == 0
    assert np.array_equal(np.load(out / "image.npy"), np.load(tmp_path / "c" / "image.npy"))
    cycle = json.loads((tmp_path / "c" / "stats.json").read_text())["cycles"]
    assert abs(stats["cycles"] - cycle) <= 0.02 * cycle
