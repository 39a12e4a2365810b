"""No space left on device names the file (issue 33).

``write`` reports ENOSPC without a file name; every writer goes through
:func:`hwsim.core.paths.atomic_write` (or :func:`~hwsim.core.paths.naming`), which adds
the path it was writing, so the error boundary's one line says which file.  Simulated
here by writers that raise ``OSError(ENOSPC)`` with no name, as ``write(2)`` does.
"""

from __future__ import annotations

import errno
import os
import sqlite3

import numpy as np
import pytest
from cli_errors import one_line_error

from hwsim.cli.commands import main
from hwsim.core.paths import atomic_write, naming

pytestmark = pytest.mark.system


def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_atomic_write_names_its_path(tmp_path):
    target = tmp_path / "kept.txt"
    target.write_text("earlier")
    with pytest.raises(OSError) as caught, atomic_write(target) as tmp:
        tmp.write_text("half")
        _no_space()
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(target)
    assert target.read_text() == "earlier"
    assert [p.name for p in tmp_path.iterdir()] == ["kept.txt"]  # no partial file left


def test_a_temporary_name_becomes_the_final_one(tmp_path):
    target = tmp_path / "x.npy"
    with pytest.raises(OSError) as caught, naming(target, tmp_path / ".x.partial.npy"):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / ".x.partial.npy"))
    assert caught.value.filename == str(target)
    with pytest.raises(OSError) as other, naming(target):  # another file's error: as it was
        raise FileNotFoundError(errno.ENOENT, "No such file", "/elsewhere")
    assert other.value.filename == "/elsewhere"


@pytest.mark.parametrize("writer", ["numpy.save", "pathlib.Path.write_text"])
def test_the_command_line_names_the_file(tmp_path, capsys, monkeypatch, writer):
    """convert (np.save) and a render's stats.json (write_text) on a full disk."""
    volume = tmp_path / "in.npy"
    np.save(volume, np.zeros((4, 4, 4), np.uint8))
    if writer == "numpy.save":
        argv, target = ["convert", str(volume), str(tmp_path / "out.npy")], "out.npy"
    else:
        out = tmp_path / "render"
        argv = ["render", "--volume", str(volume), "--image", "8", "--out", str(out), "--quiet"]
        target = "stats.json"
    monkeypatch.setattr(writer, _no_space)
    assert main(argv) == 2
    err = one_line_error(capsys, target)
    assert "no space left on device" in err.lower() and "internal error" not in err


def test_a_full_disk_under_the_sweep_database_names_it(tmp_path):
    """SQLite says "database or disk is full" (SQLITE_FULL) without a file name."""
    from hwsim.core.paths import os_problem
    from hwsim.studies.sweep.db import RunsDB

    class Full:  # the connection, its writes failing as on a full disk
        def __init__(self, conn):
            self.conn = conn

        def execute(self, sql, *args):
            if sql.startswith("INSERT"):
                exc = sqlite3.OperationalError("database or disk is full")
                exc.sqlite_errorcode = 13  # SQLITE_FULL
                raise exc
            return self.conn.execute(sql, *args)

    path = tmp_path / "runs.db"
    with RunsDB(path) as db:
        db.conn = Full(db.conn)
        with pytest.raises(OSError) as caught:
            db.insert({"key": "k", "status": "ok"})
        db.conn = db.conn.conn
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(path)
    assert str(path) in str(os_problem(caught.value))  # the boundary's one line names it
