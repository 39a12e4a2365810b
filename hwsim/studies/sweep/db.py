"""The sweep database: one SQLite row per finished run, written in its own transaction.

# Ref: shared/docs/design.md section 8 (sweeps write rows to an embedded SQL database
#      keyed by a hash of scene + architecture + fidelity + code version).

Kill-safety comes from SQLite: the database runs in WAL mode with ``synchronous=FULL``,
so a committed row survives a ``kill -9`` of the writer (and a power cut); each finished
run is one ``INSERT ... ON CONFLICT(key) DO NOTHING`` committed on its own (with
``--retry-failed``, ``DO UPDATE`` of a failed row: replaced, never deleted first), so a killed
sweep loses at most the runs that were still computing, and the ``UNIQUE`` key makes a
duplicate row impossible.  Only the process driving the sweep writes; Dask workers
return their rows to it.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import sqlite3
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError

__all__ = ["COLUMNS", "SCHEMA", "RunsDB", "by_parameters"]

SCHEMA = 1
#: Columns of table ``runs`` besides ``key``: (name, SQL type).  ``params`` and
#: ``stats`` hold JSON text (the run's parameters and its full ``stats.json`` content).
COLUMNS = (
    ("status", "TEXT NOT NULL"),  # ok | error
    ("error", "TEXT"),
    ("label", "TEXT"),
    ("params", "TEXT NOT NULL"),
    ("scene", "TEXT"),
    ("volume", "TEXT"),
    ("arch", "TEXT"),
    ("fidelity", "TEXT"),
    ("mode", "TEXT"),
    ("code_version", "TEXT"),
    ("samples", "INTEGER"),
    ("rays", "INTEGER"),
    ("cycles", "INTEGER"),
    ("clock_hz", "REAL"),
    ("frame_seconds", "REAL"),
    ("samples_per_second", "REAL"),
    ("wall_seconds", "REAL"),
    ("wall_samples_per_second", "REAL"),
    # 1: the first run of its worker process, whose wall time includes the imports and
    # numba's JIT compile (or cache load); 0: a later run of a warm process.
    ("includes_compile", "INTEGER"),
    ("technology", "TEXT"),  # hwsim.energy: the node the next three are priced in
    ("energy_joules", "REAL"),
    ("energy_per_sample_joules", "REAL"),
    ("area_mm2", "REAL"),
    ("image_sha256", "TEXT"),
    ("run_dir", "TEXT"),
    ("stats", "TEXT"),
    ("worker", "TEXT"),
    ("worker_pid", "INTEGER"),
    ("started_at", "TEXT"),
    ("finished_at", "TEXT"),
)
_NAMES = ["key", *(name for name, _ in COLUMNS)]


def check_ours(path: Path, *, must_exist: bool = False) -> None:
    """Refuse, read-only and before anything is written, a file that is not an hwsim
    results database: another application's SQLite file is never modified.

    A missing or empty file is fine (it becomes a new database) unless ``must_exist``.
    """
    if not path.exists() or path.stat().st_size == 0:
        if must_exist:
            raise InputError("no such results database", source=str(path), key="--db")
        return
    if path.is_dir():
        raise InputError("is a folder, expected an SQLite file", source=str(path), key="--db")
    try:
        conn = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        try:
            tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master")}
            schema = (
                conn.execute("SELECT value FROM meta WHERE name = 'schema'").fetchone()
                if "meta" in tables
                else None
            )
        finally:
            conn.close()
    except sqlite3.DatabaseError as exc:
        raise InputError(f"not an SQLite database: {exc}", source=str(path), key="--db") from None
    if "runs" not in tables or schema is None:
        found = ", ".join(sorted(t for t in tables if not t.startswith("sqlite_"))) or "none"
        raise InputError(
            f"not an hwsim results database (its tables: {found}); nothing was written",
            source=str(path),
            key="--db",
            allowed="a file written by hwsim sweep, or a new file",
        )


class RunsDB:
    """Table ``runs`` of an SQLite file (created on first use).

    Parameters
    ----------
    path : str or Path
        The database file (``--db``); its folder must exist.
    """

    def __init__(self, path: str | Path, *, create: bool = True) -> None:
        self.path = Path(path)
        check_ours(self.path, must_exist=not create)
        try:
            self.conn = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
            self.conn.execute("PRAGMA journal_mode=WAL")
            self.conn.execute("PRAGMA synchronous=FULL")
            cols = ",\n  ".join(f"{n} {t}" for n, t in COLUMNS)
            self.conn.execute(
                f"CREATE TABLE IF NOT EXISTS runs (\n  key TEXT NOT NULL UNIQUE,\n  {cols}\n)"
            )
            # A database from before a column existed gains it (NULL in its old rows).
            have = {r[1] for r in self.conn.execute("PRAGMA table_info(runs)")}
            for name, sql_type in COLUMNS:
                if name not in have:
                    self.conn.execute(f"ALTER TABLE runs ADD COLUMN {name} {sql_type}")
            self.conn.execute(
                "CREATE TABLE IF NOT EXISTS meta (name TEXT PRIMARY KEY, value TEXT NOT NULL)"
            )
            self.conn.execute(
                "INSERT INTO meta VALUES ('schema', ?) ON CONFLICT(name) DO NOTHING",
                (str(SCHEMA),),
            )
        except sqlite3.DatabaseError as exc:
            raise InputError(
                f"cannot open database: {exc}", source=str(self.path), key="--db"
            ) from None

    def close(self) -> None:
        self.conn.close()

    def __enter__(self) -> RunsDB:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def finished_keys(self) -> set[str]:
        """Keys of every run with a row (finished, successfully or not)."""
        return {k for (k,) in self.conn.execute("SELECT key FROM runs")}

    def statuses(self, keys: Iterable[str]) -> dict[str, str]:
        """``{key: status}`` of those of ``keys`` that have a row (one batch of a sweep)."""
        keys = list(keys)
        out: dict[str, str] = {}
        for i in range(0, len(keys), 500):  # SQLite's limit on bound parameters
            chunk = keys[i : i + 500]
            marks = ",".join("?" * len(chunk))
            query = f"SELECT key, status FROM runs WHERE key IN ({marks})"
            out.update(self.conn.execute(query, chunk).fetchall())
        return out

    def insert(self, row: dict[str, Any], *, replace_failed: bool = False) -> bool:
        """Write one finished run in its own transaction; ``False`` if the key existed.

        With ``replace_failed`` a row of the same key whose status is ``error`` is
        overwritten by this one in that same transaction (``--retry-failed``): the failed
        row stays until its replacement is committed, and a row that is ``ok`` is never
        touched.
        """
        values = [_sql_value(row.get(n)) for n in _NAMES]
        marks = ",".join("?" * len(_NAMES))
        on_conflict = "DO NOTHING"
        if replace_failed:
            sets = ", ".join(f"{n} = excluded.{n}" for n, _ in COLUMNS)
            on_conflict = f"DO UPDATE SET {sets} WHERE runs.status = 'error'"
        self.conn.execute("BEGIN IMMEDIATE")
        try:
            cur = self.conn.execute(
                f"INSERT INTO runs ({','.join(_NAMES)}) VALUES ({marks}) "
                f"ON CONFLICT(key) {on_conflict}",
                values,
            )
            self.conn.execute("COMMIT")
        except BaseException as exc:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("ROLLBACK")
            if isinstance(exc, sqlite3.OperationalError) and (err := _os_error(exc, self.path)):
                raise err from exc  # the error boundary's line names the database
            raise
        return cur.rowcount == 1

    def rows(self, where: str = "1", args: Iterable[Any] = ()) -> list[dict[str, Any]]:
        """Rows as dicts, JSON columns decoded."""
        self.conn.row_factory = sqlite3.Row
        try:
            out = []
            for r in self.conn.execute(
                f"SELECT * FROM runs WHERE {where} ORDER BY rowid", tuple(args)
            ):
                d = dict(r)
                for name in ("params", "stats"):
                    if d.get(name) is not None:
                        d[name] = json.loads(d[name])
                out.append(d)
            return out
        finally:
            self.conn.row_factory = None

    def integrity(self) -> str:
        """``PRAGMA integrity_check``: ``"ok"`` for a sound file."""
        return self.conn.execute("PRAGMA integrity_check").fetchone()[0]


#: SQLite's result codes for a failed write that are the file system's doing, as the
#: operating system's error numbers: a full disk, an I/O error, a read-only file.
_SQLITE_OS_ERRORS = {13: errno.ENOSPC, 10: errno.EIO, 8: errno.EROFS}


def _os_error(exc: sqlite3.OperationalError, path: Path) -> OSError | None:
    """The ``OSError`` naming ``path`` that a failed SQLite write stands for, else None.
    SQLite reports a full disk as "database or disk is full" without a file name."""
    code = _SQLITE_OS_ERRORS.get(getattr(exc, "sqlite_errorcode", -1) & 0xFF)
    return None if code is None else OSError(code, os.strerror(code), str(path))


def by_parameters(rows: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """``rows`` sorted by their parameters (``params``, decoded): parameter names in
    alphabetical order, each one's values ascending (numbers by value, then text, then
    anything else by its JSON); rows with equal parameters keep their order (stable)."""
    return sorted(rows, key=lambda row: _parameter_key(row.get("params") or {}))


def _parameter_key(params: dict[str, Any]) -> tuple:
    def rank(value: Any) -> tuple:
        if value is None:
            return (0, 0.0, "")
        if isinstance(value, (int, float)):  # bool too: false before true
            return (1, float(value), "")
        if isinstance(value, str):
            return (2, 0.0, value)
        return (3, 0.0, json.dumps(value, sort_keys=True, default=str))

    return tuple((name, rank(params[name])) for name in sorted(params))


def _sql_value(value: Any) -> Any:
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True, default=str)
    return value
