"""`--scheduler` against peers that are not Dask schedulers, and sweeps that stream.

A port that accepts and never answers, or answers garbage, ends `hwsim render` and
`hwsim sweep` with one line naming the address, exit 2, within Dask's connect timeout
(the subprocess timeouts below only turn a hang into a failure, they time nothing).  An
address scheme hwsim cannot use is refused by name before any connection.  With an
unreachable scheduler `--retry-failed` leaves the failed rows as they were.  A sweep of
10^5 runs writes its first row long before it has computed every key.
"""

from __future__ import annotations

import os
import socket
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.core.cluster import local_client
from hwsim.core.errors import InputError
from hwsim.studies.sweep import RunsDB, load_sweep
from hwsim.studies.sweep import runner as sweep_runner
from hwsim.studies.sweep.spec import MAX_RUNS, parse_sweep

HWSIM = [sys.executable, "-m", "hwsim.cli.commands"]
#: Only turns a hang into a test failure; the command must end within the connect timeout.
HANG_GUARD = 300


@pytest.fixture(params=["silent", "garbage"])
def hostile(request):
    """``(mode, address)`` of a local server that accepts and then says nothing, or says
    bytes that are not Dask's."""
    server = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)
            if request.param == "garbage":
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n" + bytes(range(256)) * 8)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield request.param, f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    server.close()
    for conn in held:
        conn.close()


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "3s"}
    return subprocess.run(
        [*HWSIM, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=HANG_GUARD
    )


def _one_line(proc: subprocess.CompletedProcess, mode: str, address: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert f"scheduler at {address} did not answer" in lines[0]
    if mode == "silent":
        assert "within 3 s" in lines[0]
    else:
        assert "as a Dask scheduler" in lines[0]


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nfidelity = ["functional"]\nphantom = ["ball:size=16"]\n')
    return path


def test_sweep_ends_in_one_line_against_a_hostile_peer(hostile, tmp_path, sweep_file):
    mode, address = hostile
    proc = _run(["sweep", str(sweep_file), "--scheduler", address, "--db", "r.db"], tmp_path)
    _one_line(proc, mode, address)
    assert not (tmp_path / "r.db").exists()


def test_render_ends_in_one_line_against_a_hostile_peer(hostile, tmp_path):
    mode, address = hostile
    args = ["render", "--phantom", "head:size=16", "--image", "16", "--arch", "cube4"]
    args += ["--fidelity", "cycle", "--scheduler", address, "--out", "out", "--quiet"]
    _one_line(_run(args, tmp_path), mode, address)


@pytest.mark.parametrize(
    "address",
    ["tls://127.0.0.1:8786", "inproc://127.0.0.1/1/2", "ucx://h:1", "ws://h:1", "x://h:1"],
)
def test_an_unsupported_scheme_is_refused_by_name(address, tmp_path, sweep_file, capsys):
    scheme = address.split("://")[0] + "://"
    argv = ["sweep", str(sweep_file), "--scheduler", address, "--db", str(tmp_path / "r.db")]
    assert main(argv) == 2
    render = ["render", "--phantom", "head:size=16", "--arch", "cube4", "--fidelity", "cycle"]
    assert main([*render, "--scheduler", address, "--out", str(tmp_path / "o")]) == 2
    for line in capsys.readouterr().err.strip().splitlines():
        assert f"--scheduler: unsupported address scheme '{scheme}'" in line
        assert "allowed: tcp://HOST:PORT" in line
    assert not (tmp_path / "r.db").exists()


def _rows(db: Path) -> list[tuple]:
    conn = sqlite3.connect(db)
    try:
        return conn.execute("SELECT * FROM runs ORDER BY rowid").fetchall()
    finally:
        conn.close()


def test_retry_failed_with_an_unreachable_scheduler_keeps_the_failed_rows(tmp_path, sweep_file):
    db = tmp_path / "r.db"
    (run,) = load_sweep(sweep_file).runs
    with RunsDB(db) as runs:
        runs.insert({"key": "done", "status": "ok", "params": {}, "cycles": 3})
        key = sweep_runner.run_key(run)
        runs.insert({"key": key, "status": "error", "params": run.values, "error": "boom"})
    before = _rows(db)
    with socket.socket() as closed:  # a port nobody listens on
        closed.bind(("127.0.0.1", 0))
        port = closed.getsockname()[1]
    argv = ["sweep", str(sweep_file), "--db", str(db), "--retry-failed"]
    assert main([*argv, "--scheduler", f"tcp://127.0.0.1:{port}"]) == 2
    assert _rows(db) == before


def test_a_product_past_the_bound_is_refused_from_the_lengths(tmp_path):
    side = int(MAX_RUNS ** (1 / 3)) + 2
    table = {"pipelines": list(range(1, side + 1)), "clock_hz": [1e6 + i for i in range(side)]}
    table["view"] = [[0, i % 90] for i in range(side)]
    with pytest.raises(InputError, match=r"sweep: the product of the lists has \d+ runs"):
        parse_sweep({"schema": 1, "sweep": table}, source="s.toml", base_dir=tmp_path)


def test_a_large_sweep_writes_its_first_row_before_computing_every_key(tmp_path, monkeypatch):
    """10^5 runs (1000 views x 100 image sizes): when the first row is written, only a batch or
    two of keys have been computed; the product's size is known without building it."""
    table = {
        "fidelity": ["golden"],
        "phantom": ["ball:size=8"],
        "view": [[i * 0.5 - 250, 0] for i in range(1000)],
        "image": [[8, h] for h in range(1, 101)],
    }
    plan = parse_sweep({"schema": 1, "sweep": table}, source="s.toml", base_dir=tmp_path)
    assert plan.size == len(plan.runs) == 10**5
    assert plan.runs[-1].values == {**plan.runs[0].values, "view": [249.5, 0], "image": [8, 100]}
    keys_computed = []
    first_row_at = []
    real_key, real_insert = sweep_runner.run_key, RunsDB.insert
    monkeypatch.setattr(sweep_runner, "run_key", lambda r: keys_computed.append(1) or real_key(r))

    def insert(db, row, **kw):
        first_row_at.append(len(keys_computed))
        real_insert(db, row, **kw)
        raise FirstRow  # stop the sweep at its first row

    monkeypatch.setattr(RunsDB, "insert", insert)
    with RunsDB(tmp_path / "r.db") as db, local_client(1) as client:
        with pytest.raises(FirstRow):
            sweep_runner.run_sweep(plan, db, client)
        assert len(db.rows()) == 1
    assert first_row_at == [2]  # one batch: twice the one worker's thread


class FirstRow(Exception):
    """Raised by the patched insert to stop a sweep at its first row."""
