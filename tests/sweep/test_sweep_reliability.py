"""Kill-safety of sweeps: kill -9 and resume, a worker lost mid-task, determinism.

Every process these tests start listens on 127.0.0.1 only and is killed (by process
group, or by its own pid) and waited for before the test ends.
"""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hwsim.run.fidelity import render
from hwsim.studies.sweep import RunsDB, build_run, load_sweep, local_client, run_key, run_sweep
from hwsim.studies.sweep.runner import image_digest

pytestmark = [pytest.mark.system, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]


def write_sweep(path: Path, body: str) -> Path:
    path.write_text("schema = 1\n[sweep]\n" + body)
    return path


def cli(*args: str, new_session: bool = False) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.Popen(
        [sys.executable, "-m", "hwsim.cli.commands", *args],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=new_session,
    )


def count_rows(db: Path) -> int:
    if not db.exists():
        return 0
    conn = sqlite3.connect(db, timeout=10)
    try:
        return conn.execute("SELECT count(*) FROM runs").fetchone()[0]
    except sqlite3.OperationalError:  # table not created yet
        return 0
    finally:
        conn.close()


def wait_group_gone(pgid: int) -> None:
    for _ in range(600):
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    raise AssertionError(f"processes of group {pgid} still alive")


def test_kill_9_mid_sweep_then_resume_keeps_every_row_exactly_once(tmp_path):
    sweep_file = write_sweep(
        tmp_path / "s.toml",
        'fidelity = ["functional"]\nphantom = ["head:size=48"]\n'
        "image = [40, 48, 56, 64]\npipelines = [1, 2, 3, 4]\n",
    )
    db = tmp_path / "runs.db"
    expected = {run_key(r) for r in load_sweep(sweep_file).runs}
    assert len(expected) == 16
    proc = cli(
        "sweep", str(sweep_file), "--db", str(db), "--workers", "1", "--quiet", new_session=True
    )
    try:
        while count_rows(db) < 3 and proc.poll() is None:
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver, its scheduler, nanny and worker
        proc.communicate()
        wait_group_gone(proc.pid)
    assert proc.returncode == -signal.SIGKILL
    before = count_rows(db)
    assert 3 <= before < len(expected), "the kill must land mid-sweep"

    again = cli("sweep", str(sweep_file), "--db", str(db), "--workers", "1")
    out, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert f"16 runs: {before} already in" in out and f"{16 - before} ok, 0 failed" in out

    conn = sqlite3.connect(db)
    keys = [k for (k,) in conn.execute("SELECT key FROM runs")]
    assert len(keys) == len(set(keys)) == 16 and set(keys) == expected
    assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert conn.execute("SELECT count(*) FROM runs WHERE status != 'ok'").fetchone()[0] == 0
    conn.close()


def test_a_worker_killed_mid_task_is_replaced_and_the_sweep_completes(tmp_path):
    sweep_file = write_sweep(
        tmp_path / "s.toml",
        'fidelity = ["functional"]\nphantom = ["head:size=128"]\nimage = [128]\n'
        "pipelines = [1, 2, 3, 4, 5, 6]\n",
    )
    sweep = load_sweep(sweep_file)
    db_path = tmp_path / "runs.db"
    with local_client(2) as client:
        result: dict = {}

        def drive() -> None:
            with RunsDB(db_path) as db:  # SQLite connections stay in their thread
                result["summary"] = run_sweep(sweep, db, client)

        thread = threading.Thread(target=drive, daemon=True)
        thread.start()
        victim = None
        for _ in range(3000):
            busy = {w: tasks for w, tasks in client.processing().items() if tasks}
            if busy:
                victim = next(iter(busy))
                break
            time.sleep(0.01)
        assert victim is not None, "no task ever reached a worker"
        pid = client.run(os.getpid, workers=[victim])[victim]
        os.kill(pid, signal.SIGKILL)

        def suspicious(dask_scheduler) -> int:
            return sum(ts.suspicious for ts in dask_scheduler.tasks.values())

        blamed = 0
        for _ in range(3000):  # the scheduler notices the loss and blames the task it held
            blamed = client.run_on_scheduler(suspicious)
            if blamed or not thread.is_alive():
                break
            time.sleep(0.01)
        thread.join(timeout=300)
        assert not thread.is_alive()
        assert blamed >= 1, "the killed worker held no task"
        summary = result["summary"]
        assert (summary.total, summary.ok, summary.failed) == (6, 6, 0)
        with RunsDB(db_path) as db:
            rows = db.rows()
        assert len(rows) == 6 and all(r["status"] == "ok" for r in rows)
        assert pid not in {r["worker_pid"] for r in rows}, "a row came from the killed worker"
        assert len(client.scheduler_info()["workers"]) == 2  # the nanny replaced it


def test_same_inputs_give_the_same_bits_and_cycles_in_every_process(tmp_path):
    sweep_file = write_sweep(
        tmp_path / "s.toml",
        'fidelity = ["golden", "functional"]\narch = ["volumepro500", "cube4"]\n'
        'phantom = ["head:size=32", "marschner-lobb:size=24"]\nimage = [32]\n',
    )
    procs = [
        cli(
            "sweep", str(sweep_file), "--db", str(tmp_path / f"{i}.db"), "--workers", "2", "--quiet"
        )
        for i in range(2)
    ]
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    a, b = (
        {
            r["key"]: (r["image_sha256"], r["cycles"], r["samples"])
            for r in RunsDB(tmp_path / f"{i}.db").rows()
        }
        for i in range(2)
    )
    assert len(a) == 8 and a == b
    # The digests do tell images apart: fixed point differs from float64 on every case
    # (the two machines share sample positions for parallel views, so golden may not).
    by_params = {
        (r["params"]["fidelity"], r["params"]["arch"], r["params"]["phantom"]): r["image_sha256"]
        for r in RunsDB(tmp_path / "0.db").rows()
    }
    for (fidelity, arch, phantom), digest in by_params.items():
        if fidelity == "functional":
            assert digest != by_params["golden", arch, phantom]
    run = load_sweep(sweep_file).runs[-1]
    scene, arch, fidelity, _ = build_run(run)
    here = render(scene, fidelity=fidelity, arch=arch)  # and this process agrees
    assert (image_digest(here.image), here.cycles, here.samples) == a[run_key(run)]


def test_the_local_cluster_listens_on_127_0_0_1_only():
    import psutil

    with local_client(2) as client:
        client.wait_for_workers(2)
        me = psutil.Process()
        procs = [me, *me.children(recursive=True)]
        listening = [
            c.laddr
            for p in procs
            for c in p.net_connections(kind="tcp")
            if c.status == psutil.CONN_LISTEN
        ]
    # scheduler, its HTTP server, and per worker process: worker, nanny, worker HTTP server
    assert len(listening) >= 2 + 2 * 2
    assert {addr.ip for addr in listening} == {"127.0.0.1"}
