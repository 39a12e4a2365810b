"""Evidence of the SDRAM checker (issue 35): the cycle rung's command streams replayed
through ``sdram_checker`` (tests/cosim/test_sdram_cycle_rung.py) must break when either
side is mutated -- the cycle rung's controller one clock short on tRCD, or the checker
one clock stricter on tRP -- and, as the control, pass between the unmutated sides.

The two sides share the arch file's device timings only (the checker's parameters come
from it; the rules are each side's own: hwsim/memory/sdram_kernel.py against
rtl/sdram/sdram_checker.v).  docs/evidence.md lists the measured counts.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from mutate import REPO, TIMEOUT, Edit
from simulators import require

pytestmark = pytest.mark.evidence
SIDE = Path(__file__).resolve().with_name("sdram_side.py")
#: The lit head frame of the RTL cases at 32^3 on VolumePro 500 (refreshes and row
#: conflicts in every module).
SIZE = 32

#: The cycle rung's controller issues READ one clock earlier after ACTIVATE.
SHORT_TRCD = Edit(
    "hwsim/memory/sdram_cycle.py",
    "[\n                cfg.t_rcd,\n",
    "[\n                cfg.t_rcd - 1,\n",
)
#: The checker wants one clock more between PRECHARGE and ACTIVATE/REFRESH.
LONG_TRP = Edit(
    "rtl/sdram/sdram_checker.v",
    'if (now < t_pre[bk] + T_RP) breach("tRP"',
    'if (now < t_pre[bk] + T_RP + 1) breach("tRP"',
)


def run_side(root: Path, out: Path, build: Path | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(PYTHONPATH=str(root), HWSIM_THREADS="1")
    if build is not None:
        env["HWSIM_RTL_BUILD"] = str(build)
    argv = [sys.executable, str(SIDE), str(root), str(out), str(SIZE)]
    done = subprocess.run(argv, cwd=root, env=env, capture_output=True, text=True, timeout=TIMEOUT)
    if done.returncode != 0:
        raise RuntimeError(f"sdram_side.py in {root} failed:\n{done.stderr[-2000:]}")
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def unmutated(tmp_path_factory) -> dict:
    require("icarus")
    return run_side(REPO, tmp_path_factory.mktemp("sdram") / "original.json")


def test_unmutated_replay_is_legal_and_counts_agree(unmutated):
    counts, counters = unmutated["counts"], unmutated["counters"]
    assert counts["violations"] == 0, unmutated["violations"][:5]
    assert counts["reads"] == counters["memory.sdram.bursts"]
    assert counts["activates"] == counters["memory.sdram.activates"]
    assert counts["refreshes"] == counters["memory.sdram.refreshes"] > 0


@pytest.mark.parametrize(("edit", "rule"), [(SHORT_TRCD, "tRCD"), (LONG_TRP, "tRP")])
def test_a_mutated_side_breaks_the_replay(unmutated, edit, rule, mutant, tmp_path):
    tree = mutant(edit)
    got = run_side(tree.root, tmp_path / "mutant.json", tmp_path / "rtl")
    assert unmutated["counts"]["violations"] == 0
    assert got["counts"]["violations"] > 0
    assert all(f"VIOLATION {rule} " in line for line in got["violations"]), got["violations"][:3]
