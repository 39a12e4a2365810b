"""The local Dask cluster on a busy machine: scratch files of its own, workers that log as
the parent does (hwsim.core.cluster, hwsim.core.logs)."""

from __future__ import annotations

import fcntl
import logging
import tempfile
from pathlib import Path

import dask
import pytest

from hwsim.core import cluster, logs
from hwsim.core.cluster import local_client

pytestmark = pytest.mark.system


@pytest.fixture
def verbosity():
    """Set hwsim's verbosity for one test; levels and state restored afterwards."""
    names = [None, *logs.OWN, *logs.LIBRARIES, *(name for name, _, _ in logs.BENIGN)]
    saved = [(logging.getLogger(n), logging.getLogger(n).level) for n in names]
    filters = {n: list(logging.getLogger(n).filters) for n in names}
    handlers = list(logging.getLogger().handlers)
    state = dict(logs._state)
    yield logs.configure_logging
    for logger, level in saved:
        logger.setLevel(level)
        logger.filters[:] = filters[logger.name if logger.name != "root" else None]
    logging.getLogger().handlers[:] = handlers
    logs._state.update(state)


@pytest.mark.slow
def test_a_local_cluster_never_touches_the_shared_scratch_space(tmp_path, verbosity):
    """Dask's shared dask-scratch-space holds what killed workers left; purging it while a
    cluster starts on a busy machine made Dask warn (an error under pytest).  hwsim's
    cluster keeps to a fresh directory, removed at close."""
    verbosity(0)
    shared = tmp_path / "dask-scratch-space"
    stale = shared / "worker-killed"
    stale.mkdir(parents=True)
    (shared / "worker-killed.dirlock").touch()  # unlocked: Dask would purge it
    with dask.config.set({"temporary-directory": str(tmp_path)}):
        with local_client(1) as client:
            client.wait_for_workers(1)
            scheduler_dir = Path(client.cluster.scheduler.local_directory)
            (worker,) = client.scheduler_info()["workers"].values()
            worker_dir = Path(worker["local_directory"])
    assert stale.is_dir()  # nobody purged the shared space: nobody used it
    own = scheduler_dir.parents[1]
    assert own.parent == Path(tempfile.gettempdir()) and own.name.startswith("hwsim-dask-")
    assert worker_dir.is_relative_to(own)
    assert not own.exists()  # removed at close


@pytest.mark.slow
@pytest.mark.parametrize(("verbose", "level"), [(0, logging.ERROR), (1, logging.INFO)])
def test_the_workers_log_as_the_parent_does(verbose, level, verbosity):
    verbosity(verbose)
    with local_client(1) as client:
        client.wait_for_workers(1)
        (theirs,) = client.run(logs.verbosity).values()
        (distributed,) = client.run(logging.getLogger("distributed").getEffectiveLevel).values()
    assert (theirs, distributed) == (verbose, level)


def test_what_a_killed_cluster_left_is_removed_what_a_running_one_holds_is_not(tmp_path):
    """A scratch directory's lock is held while its cluster runs; a killed process's is
    free, and the next cluster removes that directory."""
    prefix = cluster._SCRATCH_PREFIX
    for name in ("killed", "running"):
        (tmp_path / f"{prefix}{name}" / "dask-scratch-space").mkdir(parents=True)
        (tmp_path / f"{prefix}{name}.lock").touch()
    unrelated = tmp_path / f"{prefix}no-lock"  # no lock file: not ours to judge
    unrelated.mkdir()
    with open(tmp_path / f"{prefix}running.lock", "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        cluster._remove_orphans(tmp_path)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == [f"{prefix}no-lock", f"{prefix}running", f"{prefix}running.lock"]
