"""Malformed report inputs (stats.json, image.npy, trade.json, figures.json): each reads
and its tables build, or is refused in one line naming the file and a key path.

The documents are real ones (a cycle render and a trade made once per module, the shipped
figures table), mutated as the TOML files are (:mod:`mutate`) and written with
``json.dumps``, which writes NaN and Infinity as JavaScript does.
"""

from __future__ import annotations

import itertools
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from fuzz_documents import FUZZ, JSON_VALUES, Mutation, loads_or_refuses, mutated, mutations
from hypothesis import assume, example, given
from hypothesis import strategies as st

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.core.json_input import MAX_DEPTH
from hwsim.report import plots, report
from hwsim.report import studies as report_studies
from hwsim.report.energy import energy_blocks

pytestmark = pytest.mark.fuzz

FIGURES = report_studies.SHIPPED_FIGURES
_NAMES = itertools.count()


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    common = ["--phantom", "head:size=16", "--image", "16", "--quiet"]
    render = ["render", *common, "--arch", "cube4", "--fidelity", "cycle"]
    assert main([*render, "--out", str(root / "run")]) == 0
    trade = ["trade", "--arch", "volumepro500", "--rungs", "golden,functional", "--quiet"]
    assert main([*trade, "--image", "16", "--size", "16", "--out", str(root / "trade")]) == 0
    return root


def _copy(runs: Path, tmp_path: Path, name: str) -> Path:
    folder = tmp_path / f"{name}-{next(_NAMES)}"
    shutil.copytree(runs / name, folder)
    return folder


def _run_tables(stats_path: Path) -> report.RunRecord:
    """What the report makes of one run without rendering a reference: its tables and
    plots (the image comparison renders golden: covered by tests/report)."""
    run = report.load_run(stats_path.parent)
    out = stats_path.parent / "out"
    out.mkdir(exist_ok=True)
    report._summary_table(run)
    report._split_blocks(run.stats)
    report._unit_blocks(run.stats, out, 1)
    report._bandwidth_blocks(run.stats, out, 1)
    report._published_blocks(run)
    energy_blocks(run.stats, out, 1, "not recorded")
    return run


class _Axes:
    """Matplotlib axes that draw nothing: a plot's data is still computed (its arithmetic
    on the file's values is what the property checks), in microseconds."""

    def __getattr__(self, name: str):
        return lambda *args, **kwargs: None


def _no_drawing(path: Path, names: list[str], xlabel: str, draw) -> Path:
    draw(_Axes())
    return path


def _stats_doc(runs: Path) -> dict:
    return json.loads((runs / "run" / "stats.json").read_text())


@FUZZ
@given(data=st.data())
def test_stats_json(runs, tmp_path, monkeypatch, data):
    monkeypatch.setattr(plots, "_bars", _no_drawing)
    doc = _stats_doc(runs)
    m = data.draw(mutations(doc, JSON_VALUES), label="mutation")
    folder = _copy(runs, tmp_path, "run")
    (folder / "stats.json").write_text(json.dumps(mutated(doc, m)))
    loads_or_refuses(_run_tables, folder / "stats.json")


@pytest.mark.parametrize(
    "text",
    ["[1, 2]", "{}", "[" * 100_000 + "]" * 100_000, '{"a": ' * 100 + "1" + "}" * 100, "nul"],
    ids=["list", "empty", "deep-arrays", "deep-objects", "malformed"],
)
def test_issue_stats_examples(runs, tmp_path, text):
    folder = _copy(runs, tmp_path, "run")
    (folder / "stats.json").write_text(text)
    with pytest.raises(InputError, match="stats.json: "):
        report.load_run(folder)


def test_depth_limit_counts_brackets_not_strings(runs, tmp_path):
    folder = _copy(runs, tmp_path, "run")
    doc = _stats_doc(runs)
    doc["scene"]["name"] = "[" * (MAX_DEPTH + 10)  # inside a string: not nesting
    (folder / "stats.json").write_text(json.dumps(doc))
    assert report.load_run(folder).stats["scene"]["name"].startswith("[[[")


@pytest.mark.parametrize(
    "image",
    [
        np.zeros(5),
        np.full((4, 4, 4), np.nan),
        np.zeros((4, 4, 9)),
        np.array(["a"]),
        np.zeros((0, 4)),
    ],
    ids=["1-D", "all-NaN", "9-channels", "strings", "empty"],
)
def test_issue_image_examples(runs, tmp_path, image):
    folder = _copy(runs, tmp_path, "run")
    np.save(folder / "image.npy", image)
    with pytest.raises(InputError, match="image.npy: "):
        report.load_run(folder)


def _trade(path: Path):
    return report_studies.trade_blocks(path.parent, path.parent, 1)


@FUZZ
@given(data=st.data())
def test_trade_json(runs, tmp_path, data):
    doc = json.loads((runs / "trade" / "trade.json").read_text())
    m = data.draw(mutations(doc, JSON_VALUES), label="mutation")
    folder = _copy(runs, tmp_path, "trade")
    (folder / "trade.json").write_text(json.dumps(mutated(doc, m)))
    loads_or_refuses(_trade, folder / "trade.json")


def _figures(path: Path):
    return report_studies.figures_blocks(path, path.parent)


@FUZZ
@given(m=mutations(json.loads(FIGURES.read_text()), JSON_VALUES))
@example(m=Mutation("replace", ("rows",), {}))
@example(m=Mutation("replace", ("rows", 0, "difference"), None))
def test_figures_json(tmp_path, m):
    path = tmp_path / f"figures-{next(_NAMES)}" / "figures.json"
    path.parent.mkdir()
    path.write_text(json.dumps(mutated(json.loads(FIGURES.read_text()), m)))
    loads_or_refuses(_figures, path)


# --------------------------------------------------------------------------- sweep database

_SWEEP_ROW = {
    "key": "k1",
    "label": "arch=cube4",
    "status": "ok",
    "cycles": 100,
    "frame_seconds": 1e-3,
    "samples_per_second": 1e9,
    "wall_seconds": 0.1,
    "includes_compile": 1,
    "error": None,
    "params": {"arch": "cube4"},
    "stats": {  # the run's stats.json: what hwsim.run.stats_schema.Stats requires of it
        "fidelity": "functional",
        "sampling": "ray",
        "arch": "cube4",
        "scene": {"render": {"mode": "composite"}},
        "volume": {"name": "ball", "shape_zyx": [16, 16, 16], "dtype": "uint8"},
        "samples": 10,
        "wall_seconds": 0.1,
    },
}


def _sweep_db(folder: Path, row: dict) -> Path:
    from hwsim.studies.sweep.db import RunsDB

    path = folder / f"runs-{next(_NAMES)}.db"
    with RunsDB(path) as db:
        db.insert(row)
    return path


def _sweep(path: Path):
    return report_studies.sweep_blocks(path)


@FUZZ
@given(
    m=st.sampled_from(sorted(set(_SWEEP_ROW) - {"key"})).flatmap(
        lambda k: st.builds(Mutation, st.just("replace"), st.just((k,)), JSON_VALUES)
    )
)
def test_sweep_database_row(tmp_path, m):
    try:
        path = _sweep_db(tmp_path, mutated(_SWEEP_ROW, m))
    except (OverflowError, sqlite3.IntegrityError):  # not a row SQLite lets anyone write
        assume(False)
    loads_or_refuses(_sweep, path)


def test_the_unmutated_sweep_row_reads(tmp_path):
    assert _sweep(_sweep_db(tmp_path, _SWEEP_ROW))[1] == ("p", "1 run(s), 0 failed.")


_NOT_JSON = ["{", "[" * 100_000 + "]" * 100_000]


@pytest.mark.parametrize(
    ("column", "text"),
    [("params", t) for t in [*_NOT_JSON, "[1, 2]"]]
    + [("stats", t) for t in [*_NOT_JSON, "[1, 2]", '{"samples": 10}']],
)
def test_sweep_database_json_columns(tmp_path, column, text):
    path = _sweep_db(tmp_path, _SWEEP_ROW)
    with sqlite3.connect(path) as conn:
        conn.execute(f"UPDATE runs SET {column} = ?", (text,))
    with pytest.raises(InputError, match=r"runs-\d+\.db: runs"):
        report_studies.sweep_blocks(path)
