"""With --scheduler, workers use the client's HWSIM_* settings (issue 33).

A remote cluster's workers were started with their own environment; the command line
checks its own values and sends them with the work (``hwsim.core.env.Carried``), so a
worker's ``HWSIM_MAX_SAMPLES`` or ``HWSIM_THREADS`` never changes what the client asked.
The cluster here is a ``LocalCluster`` whose worker processes get other values.
"""

from __future__ import annotations

import sqlite3

import pytest
from distributed import Client, LocalCluster

from hwsim.cli.commands import main
from hwsim.core import env

pytestmark = [pytest.mark.system, pytest.mark.slow]

WORKER_ENV = {"HWSIM_THREADS": "7", "HWSIM_MAX_SAMPLES": "1"}


@pytest.fixture(scope="module")
def cluster():
    """A scheduler whose one worker process has WORKER_ENV in its environment.

    Given as the nannies' ``env`` argument: set inside the worker process and above this
    process's own variables (``pre-spawn-environ`` was written into this process's
    environment and stayed: every later test on that xdist worker ran with
    HWSIM_MAX_SAMPLES=1; ``nanny.environ`` yields to a variable this process has)."""
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None, env=WORKER_ENV,
    ) as local, Client(local) as client:  # fmt: skip
        yield local.scheduler_address, client


def test_a_local_cluster_leaves_this_process_s_environment_alone(monkeypatch):
    """hwsim's own local cluster gives its workers HWSIM_THREADS=1 inside their
    processes; through Dask's pre-spawn-environ it was also written into the calling
    process's environment and stayed (an API user's later renders ran on one thread)."""
    import os

    from hwsim.core.cluster import local_client

    monkeypatch.delenv("HWSIM_THREADS", raising=False)
    with local_client(1) as client:
        assert client.submit(env.value, "HWSIM_THREADS", pure=False).result() == 1
        assert "HWSIM_THREADS" not in os.environ
    assert "HWSIM_THREADS" not in os.environ


def test_work_carries_the_client_s_values(cluster, monkeypatch):
    _, client = cluster
    monkeypatch.setenv("HWSIM_THREADS", "3")
    monkeypatch.delenv("HWSIM_MAX_SAMPLES", raising=False)
    assert client.submit(env.value, "HWSIM_THREADS", pure=False).result() == 7  # its own
    carried = env.Carried(env.value, env.settings())
    assert client.submit(carried, "HWSIM_THREADS", pure=False).result() == 3
    assert client.submit(carried, "HWSIM_MAX_SAMPLES", pure=False).result() is None
    assert "HWSIM_RTL_BUILD" not in env.settings()  # a folder of this machine stays here


def test_a_sweep_on_a_scheduler_renders_with_the_client_s_budget(cluster, tmp_path, monkeypatch):
    """The worker alone would refuse every frame (HWSIM_MAX_SAMPLES=1 there)."""
    address, _ = cluster
    monkeypatch.delenv("HWSIM_MAX_SAMPLES", raising=False)
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('schema = 1\n[sweep]\nphantom = ["ball:size=8"]\nfidelity = ["golden"]\n'
                     "image = [8]\n")  # fmt: skip
    db = tmp_path / "runs.db"
    assert main(["sweep", str(sweep), "--scheduler", address, "--db", str(db), "--quiet"]) == 0
    with sqlite3.connect(db) as conn:
        statuses = [row[0] for row in conn.execute("SELECT status FROM runs")]
    assert statuses == ["ok"], statuses
