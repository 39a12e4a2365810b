"""Design-space sweeps on Dask with one SQLite row per run (design sections 8 and 9)."""

from hwsim.studies.sweep.db import RunsDB
from hwsim.studies.sweep.runner import SweepSummary, execute_run, local_client, run_sweep
from hwsim.studies.sweep.spec import RunSpec, Sweep, build_run, load_sweep, parse_sweep, run_key

__all__ = [
    "RunSpec",
    "RunsDB",
    "Sweep",
    "SweepSummary",
    "build_run",
    "execute_run",
    "load_sweep",
    "local_client",
    "parse_sweep",
    "run_key",
    "run_sweep",
]
