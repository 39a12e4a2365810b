"""Progress of every rung and way of rendering: the callback sees the done fraction only
grow and end at 1; first-run work (numba compiling, the RTL build) is announced exactly
when it happens (a cold cache), not when the kernels load from the cache."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from hwsim.cli.progress import COMPILING, progress_bar
from hwsim.core.notices import first_run
from hwsim.run.fidelity import render
from hwsim.run.turntable import render_turntable
from hwsim.spec.scene import load_scene

pytestmark = pytest.mark.system


def small_scene():
    """The default scene on a 16^3 head phantom, a 16 x 16 image."""
    import dataclasses

    scene = load_scene("head")
    volume = dataclasses.replace(scene.volume, params=(("size", 16),))
    view = dataclasses.replace(scene.view, width=16, height=16)
    return scene.replace(volume=volume, view=view)


class Recorder:
    """A progress callback that records ``done / total``."""

    def __init__(self) -> None:
        self.fractions: list[float] = []

    def __call__(self, done: int, total: int, what: str | None = None) -> None:
        assert total > 0 and 0 <= done <= total, (done, total)
        self.fractions.append(done / total)

    def check(self) -> None:
        assert self.fractions, "progress was never reported"
        assert self.fractions == sorted(self.fractions), self.fractions
        assert self.fractions[-1] == 1.0


RUNGS = [
    ("golden", None, {}),
    ("golden", "cube4", {}),
    ("functional", "volumepro500", {}),
    ("transaction", "cube4", {}),
    ("transaction", "volumepro500", {}),
    ("transaction", "volumepro500", {"steady_state": True}),
    ("transaction", "volumepro1000", {}),
    ("transaction", "vizard2", {}),
    ("transaction", "vizard2", {"timing_only": True}),
    ("cycle", "cube4", {}),
    ("cycle", "volumepro500", {}),
    ("cycle", "vizard2", {}),
]


@pytest.mark.parametrize(("fidelity", "arch", "options"), RUNGS)
def test_every_rung_reports_growing_progress_that_ends_at_one(fidelity, arch, options):
    progress = Recorder()
    render(small_scene(), fidelity=fidelity, arch=arch, progress=progress, **options)
    progress.check()


@pytest.mark.parametrize(
    ("arch", "model"),
    [
        ("cube4", "models.machines.cube4.transaction.Cube4Transaction"),
        ("volumepro500", "models.machines.volumepro.transaction.SlabTransaction"),
        ("vizard2", "models.machines.vizard2.transaction.VizardTransaction"),
    ],
)
def test_the_transaction_rung_reports_while_its_event_model_runs(arch, model, monkeypatch):
    """The image's steps are the first half of the bar; the event model's own work items
    (slices, beam groups, ray packets) drive the second, while it runs."""
    import importlib

    module, name = model.rsplit(".", 1)
    cls = getattr(importlib.import_module(module), name)
    running, during = [False], []
    plain_run = cls.run

    def run(self):
        running[0] = True
        try:
            return plain_run(self)
        finally:
            running[0] = False

    monkeypatch.setattr(cls, "run", run)
    progress = Recorder()

    def record(done, total, what=None):
        progress(done, total)
        if running[0]:
            during.append(done / total)

    render(small_scene(), fidelity="transaction", arch=arch, progress=record)
    progress.check()
    assert len(during) >= 2 and during[0] < 1.0 and min(during) >= 0.5, during


@pytest.mark.parametrize("fidelity", ["transaction", "cycle"])
def test_a_supervolume_reports_its_bricks(fidelity):
    """A 28^3 head on a VolumePro 500 that holds 16^3: bricks, each a frame."""
    import dataclasses

    from hwsim.run.fidelity import resolve_arch

    machine = dataclasses.replace(resolve_arch("volumepro500"), max_volume=(16, 16, 16))
    scene = small_scene()
    scene = scene.replace(volume=dataclasses.replace(scene.volume, params=(("size", 28),)))
    progress = Recorder()
    run = render(scene, fidelity=fidelity, arch=machine, progress=progress)
    assert run.derived["supervolume"]["bricks"] > 1
    progress.check()
    assert len(progress.fractions) == run.derived["supervolume"]["bricks"]


def test_a_turntable_reports_its_frames():
    progress = Recorder()
    render_turntable(small_scene(), 3, 30.0, progress=progress, fidelity="functional")
    progress.check()


def test_first_run_work_is_shown_while_it_runs_and_summed_at_the_end(capsys):
    with progress_bar(False, "render"), first_run("building RTL (Verilator), first run only"):
        pass
    err = capsys.readouterr().err
    assert "building RTL (Verilator), first run only: " in err and "cached" in err
    with progress_bar(True, "render"), first_run("building RTL (Verilator), first run only"):
        pass
    assert capsys.readouterr().err == ""


COMPILE_ONE_KERNEL = """
from hwsim.cli.progress import progress_bar
with progress_bar(False, "render"):
    from hwsim.golden.power import power_scalar
    assert power_scalar(2.0, 3) == 8.0
"""


def test_the_compile_notice_appears_exactly_when_the_kernel_cache_is_cold(tmp_path):
    """One small kernel in an empty numba cache: compiled (and announced) by the first
    process, loaded silently by the second."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}

    def stderr() -> str:
        cmd = [sys.executable, "-c", COMPILE_ONE_KERNEL]
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        return done.stderr

    cold, warm = stderr(), stderr()
    assert COMPILING in cold and f"{COMPILING}: " in cold
    # To a pipe (a log): a start line and the summary, no spinner redrawn into it.
    assert [line for line in cold.splitlines() if COMPILING in line or not line.strip()] == [
        f"{COMPILING} ...",
        cold.splitlines()[-1],
    ], cold
    assert COMPILING not in warm, warm
