"""One shape for stats.json (issue 33): every stats.json a real render writes, on every
rung and with every optional block (energy and area, a split frame, a turntable, a timed
frame without its image), and every stats column a sweep stores, validates against the
model the report reads (hwsim.run.stats_schema.Stats)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.core.models import validate
from hwsim.report.inputs import read_stats, read_sweep_rows
from hwsim.run.stats_schema import Stats

pytestmark = pytest.mark.system

COMMON = ["render", "--phantom", "head:size=16", "--image", "16", "--quiet"]
CASES = {
    "golden": ["--fidelity", "golden"],
    "golden-slice-parallel": ["--fidelity", "golden", "--arch", "cube4"],
    "functional": ["--fidelity", "functional", "--arch", "volumepro500"],
    "transaction-timing-only": ["--fidelity", "transaction", "--timing-only"],
    "cycle-priced": ["--fidelity", "cycle", "--arch", "cube4", "--technology", "cmos250"],
    "cycle-split": ["--fidelity", "cycle", "--arch", "cube4", "--workers", "2"],
    "turntable": ["--fidelity", "functional", "--frames", "2"],
}
#: Blocks each case must have written (the model would accept them absent or null).
BLOCKS = {"cycle-priced": ("energy", "area", "technology"), "cycle-split": ("split",)}


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("stats")
    out = {}
    for name, args in CASES.items():
        assert main([*COMMON, *args, "--out", str(root / name)]) == 0, name
        out[name] = root / name / "stats.json"
    return out


@pytest.mark.parametrize("name", CASES)
def test_every_rung_writes_what_the_report_reads(written, name):
    path = written[name]
    stats = read_stats(path)  # the report's check (raises InputError on a mismatch)
    model = validate(stats, Stats, str(path))
    for block in BLOCKS.get(name, ()):
        assert getattr(model, block) is not None, f"{name} wrote no {block}"


def test_a_written_file_missing_a_declared_key_is_refused(written, tmp_path):
    doc = json.loads(written["cycle-priced"].read_text())
    del doc["area"]["units"]
    path = tmp_path / "stats.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"stats.json: area.units: is required"):
        read_stats(path)


def test_every_stats_column_a_sweep_stores_is_a_stats_json(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'schema = 1\n[sweep]\nphantom = ["ball:size=16"]\nimage = [16]\n'
        'fidelity = ["golden", "cycle"]\narch = ["cube4"]\n'
    )
    db = tmp_path / "runs.db"
    assert main(["sweep", str(sweep), "--db", str(db), "--workers", "1", "--quiet"]) == 0
    rows = read_sweep_rows(db)  # each row's stats column checked against Stats
    assert len(rows) == 2 and all(r["status"] == "ok" and r["stats"] for r in rows)
