"""Hold-out check for issue 33: bad inputs of the issue's classes that no test names.

Each case builds its files in a fresh folder and runs the installed command line in a
child process (``python -m hwsim.cli.commands``, warnings as errors, no ``HWSIM_*``
variables but its own), then asserts what the issue asks of every bad input: exit
status 2, exactly one ``hwsim: error:`` line on stderr, no traceback, and every input
file byte for byte as it was; or, where the input is odd but valid ("either"), a correct
result (exit 0, nothing on stderr) with the inputs untouched.

Classes: a value of the wrong type in each file kind (architecture, scene, technology,
sweep, transfer file, report inputs); operating-system errors on path-taking flags;
inputs named as outputs (directly or inside another file); environment values; formats.

    .venv/bin/python tests/fuzz/holdout_cases.py            # every case, pass rate
    .venv/bin/python tests/fuzz/holdout_cases.py -k nrrd -v # the cases matching 'nrrd'

``tests/fuzz/test_holdout.py`` runs a bounded sample in CI.  The cases are tables, one
module per input class (``holdout_types.py``, ``holdout_paths.py``,
``holdout_values.py``) over the shared builders of ``holdout_files.py``; this module
runs them.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import holdout_paths
import holdout_types
import holdout_values
from holdout_files import _SOCKETS, HWSIM, TIMEOUT, Case, _valid_stats

__all__ = ["CASES", "Case", "main", "run", "run_case"]

#: Every case, class by class (CI runs the first two of each class: the order is part of
#: the test ids).
CASES: list[Case] = [*holdout_types.CASES, *holdout_paths.CASES, *holdout_values.CASES]

# ------------------------------------------------------------------ running


def _digest(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def run_case(c: Case, root: Path) -> tuple[bool, str]:
    """Run one case in a fresh folder under ``root``: (passed, why not)."""
    d = root / c.name
    d.mkdir()
    setup = c.build(d)
    before = {p: _digest(p) for p in setup.keep}
    environ = {k: v for k, v in os.environ.items() if not k.startswith("HWSIM_")}
    env = {**environ, "PYTHONWARNINGS": "error", **setup.env}
    try:
        done = subprocess.run(
            [*HWSIM, *setup.argv], cwd=d, env=env, capture_output=True, text=True,
            timeout=TIMEOUT,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        return False, f"still running after {TIMEOUT} s (a bad input that was not refused)"
    err = done.stderr
    changed = [str(p.name) for p in setup.keep if _digest(p) != before[p]]
    if changed:
        return False, f"input changed: {changed}; exit {done.returncode}: {err[-300:]}"
    if "Traceback" in err or "internal error" in err:
        return False, f"exit {done.returncode}: {err.strip()[-400:]}"
    if done.returncode == 0 and setup.expect == "either" and not err.strip():
        return True, "correct result"
    lines = err.strip().splitlines()
    if done.returncode == 2 and len(lines) == 1 and lines[0].startswith("hwsim: error: "):
        return True, lines[0]
    return False, f"exit {done.returncode}: {err.strip()[-400:]}"


def run(cases: list[Case], jobs: int = 4, verbose: bool = False) -> list[tuple[Case, bool, str]]:
    with tempfile.TemporaryDirectory(prefix="hwsim-holdout-") as tmp:
        _valid_stats()  # once, before the threads
        with ThreadPoolExecutor(jobs) as pool:
            results = list(pool.map(lambda c: (c, *run_case(c, Path(tmp))), cases))
    for sock in _SOCKETS:
        sock.close()
    for c, ok, why in results:
        if verbose or not ok:
            print(f"{'PASS' if ok else 'FAIL'} {c.kind:<24} {c.name}: {why}")
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only cases whose name holds this")
    parser.add_argument("-j", type=int, default=4, help="cases at once (4)")
    parser.add_argument("-v", action="store_true", help="print passing cases too")
    args = parser.parse_args(argv)
    cases = [c for c in CASES if args.k in c.name]
    results = run(cases, args.j, args.v)
    passed = sum(ok for _, ok, _ in results)
    print(f"hold-out: {passed}/{len(results)} passed ({100 * passed / max(len(results), 1):.0f}%)")
    return 0 if passed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
