"""The runs table: one row per key whatever happens, WAL mode, integrity check."""

from __future__ import annotations

import sqlite3

import pytest

from hwsim.core.errors import InputError
from hwsim.studies.sweep import RunsDB


def row(key: str, status: str = "ok", **extra) -> dict:
    return {"key": key, "status": status, "params": {"pipelines": 2}, "cycles": 10, **extra}


def test_insert_is_once_per_key_and_reports_the_conflict(tmp_path):
    with RunsDB(tmp_path / "r.db") as db:
        assert db.insert(row("a")) is True
        assert db.insert(row("a", cycles=99)) is False  # ON CONFLICT DO NOTHING
        assert db.insert(row("b", "error", error="boom")) is True
        rows = db.rows()
        assert [(r["key"], r["cycles"]) for r in rows] == [("a", 10), ("b", 10)]
        assert rows[0]["params"] == {"pipelines": 2}
        assert db.finished_keys() == {"a", "b"}
        assert db.integrity() == "ok"


def test_the_key_is_unique_in_the_schema_itself(tmp_path):
    RunsDB(tmp_path / "r.db").insert(row("a"))
    conn = sqlite3.connect(tmp_path / "r.db")
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    with pytest.raises(sqlite3.IntegrityError):
        conn.execute("INSERT INTO runs (key, status, params) VALUES ('a', 'ok', '{}')")


def test_retry_failed_replaces_only_failed_rows_in_place(tmp_path):
    with RunsDB(tmp_path / "r.db") as db:
        db.insert(row("a"))
        db.insert(row("b", "error", error="boom"))
        assert db.statuses(["a", "b", "c"]) == {"a": "ok", "b": "error"}
        assert not db.insert(row("b"))  # without replace_failed the failed row stays
        assert db.insert(row("b"), replace_failed=True)
        assert not db.insert(row("a", "error", error="late"), replace_failed=True)
        assert [(r["key"], r["status"], r["error"]) for r in db.rows()] == [
            ("a", "ok", None),
            ("b", "ok", None),
        ]


def test_a_file_that_is_not_a_database_is_bad_input(tmp_path):
    bad = tmp_path / "r.db"
    bad.write_text("not sqlite " * 100)
    with pytest.raises(InputError, match="r.db: --db: not an SQLite database"):
        RunsDB(bad)


def test_a_database_from_before_a_column_gains_it(tmp_path):
    """A results file written before the energy columns existed opens, gains them (NULL
    in its old rows) and takes new rows."""
    path = tmp_path / "old.db"
    conn = sqlite3.connect(path)
    conn.execute(
        "CREATE TABLE runs (key TEXT NOT NULL UNIQUE, status TEXT NOT NULL, params TEXT NOT NULL)"
    )
    conn.execute("CREATE TABLE meta (name TEXT PRIMARY KEY, value TEXT NOT NULL)")
    conn.execute("INSERT INTO meta VALUES ('schema', '1')")
    conn.execute("INSERT INTO runs VALUES ('old', 'ok', '{}')")
    conn.commit()
    conn.close()
    with RunsDB(path) as db:
        db.insert(row("new", energy_joules=1.5e-3, area_mm2=12.0, technology="cmos45"))
        rows = {r["key"]: r for r in db.rows()}
    assert rows["old"]["energy_joules"] is None
    assert (rows["new"]["energy_joules"], rows["new"]["area_mm2"]) == (1.5e-3, 12.0)


def test_rows_sort_by_their_parameters_names_then_values(tmp_path):
    from hwsim.studies.sweep.db import by_parameters

    params = [
        {"pipelines": 8, "arch": "cube4"},
        {"pipelines": 2, "arch": "volumepro500"},
        {"pipelines": 16, "arch": "cube4"},
        {"pipelines": 2, "arch": "cube4"},
        {"pipelines": 2, "arch": "cube4", "size": None},
    ]
    with RunsDB(tmp_path / "r.db") as db:
        for i, p in enumerate(params):
            db.insert(row(f"k{i}", params=p))
        rows = by_parameters(db.rows())
    # arch first (alphabetically before pipelines), then pipelines numerically (2 < 8 < 16).
    assert [r["key"] for r in rows] == ["k3", "k4", "k0", "k2", "k1"]
    same = [row("x1", params={"a": 1}), row("x0", params={"a": 1})]
    assert [r["key"] for r in by_parameters(same)] == ["x1", "x0"]  # stable
