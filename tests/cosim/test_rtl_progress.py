"""The rtl rung's progress and first-run notice: samples taken reported up to the whole
frame; the Verilog export and Verilator build announced exactly when they run (a build
folder without the model), never for a cached build."""

from __future__ import annotations

import pytest
from simulators import require

from hwsim.core import notices
from hwsim.run.fidelity import render
from hwsim.spec.scene import load_scene

pytestmark = pytest.mark.cosim


def small_scene():
    """test_top_rung's scene (``--phantom head:size=8 --mode composite --view 30,20
    --image 12``): the same top, so the same build folder."""
    import dataclasses

    scene = load_scene("head")
    volume = dataclasses.replace(scene.volume, params=(("size", 8),))
    view = dataclasses.replace(scene.view, width=12, height=12, azimuth=30, elevation=20)
    render_ = dataclasses.replace(scene.render, mode="composite")
    return scene.replace(volume=volume, view=view, render=render_)


class Heard:
    def __init__(self) -> None:
        self.started: list[str] = []

    def start(self, what: str) -> None:
        self.started.append(what)

    def end(self, what: str) -> None:
        pass


def _rtl_frame(progress):
    scene = small_scene()
    heard = Heard()
    with notices.listening(heard):
        render(scene, fidelity="rtl", arch="cube4", progress=progress)
    return heard.started


def _built() -> bool:
    """Whether the Verilator model of the scene's top (the frame the rung renders) is
    already built."""
    from hwsim.run.fidelity import RenderRequest, _prepare
    from rtl.frame import prepare
    from rtl.rung import build_dir

    frame = _prepare(small_scene(), RenderRequest(fidelity="rtl", arch="cube4")).frame()
    return (build_dir(prepare(frame), "verilator") / "Vcube4_bench").is_file()


def test_the_rtl_rung_reports_progress_and_announces_only_a_first_build():
    require("verilator")
    built = _built()
    fractions: list[float] = []
    started = _rtl_frame(lambda done, total, what=None: fractions.append(done / total))
    assert started == ([] if built else ["building RTL (Verilator), first run only"])
    assert fractions and fractions == sorted(fractions) and fractions[-1] == 1.0
    again = _rtl_frame(None)
    assert again == []  # built now: nothing announced
