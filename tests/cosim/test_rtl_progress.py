"""The rtl rung's progress and first-run notice: samples taken reported up to the whole
frame; the Verilog export and Verilator build announced exactly when they run (a build
folder without the model), never for a cached build."""

from __future__ import annotations

import pytest
from simulators import require

from hwsim.core import notices
from hwsim.run.fidelity import render
from hwsim.spec.overrides import apply_overrides
from hwsim.spec.scene import load_scene

pytestmark = pytest.mark.cosim
# test_top_rung's scene: the same top, so the same build folder.
SCENE = ["--phantom", "head:size=8", "--mode", "composite", "--view", "30,20", "--image", "12"]


class Heard:
    def __init__(self) -> None:
        self.started: list[str] = []

    def start(self, what: str) -> None:
        self.started.append(what)

    def end(self, what: str) -> None:
        pass


def _rtl_frame(progress):
    from hwsim.cli.commands import build_parser

    args = build_parser().parse_args(["render", *SCENE])
    scene = apply_overrides(load_scene(args.scene), args)
    heard = Heard()
    with notices.listening(heard):
        render(scene, fidelity="rtl", arch="cube4", progress=progress)
    return heard.started


def _built() -> bool:
    """Whether the Verilator model of the scene's top is already built."""
    from hwsim.cli.commands import build_parser
    from hwsim.run.fidelity import resolve_arch
    from models.frame import frame_of
    from rtl.frame import prepare
    from rtl.rung import build_dir

    args = build_parser().parse_args(["render", *SCENE])
    scene = apply_overrides(load_scene(args.scene), args)
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import load_volume

    volume = load_volume(scene.volume, scene.base_dir)
    transfer = resolve_transfer(scene.transfer, volume, scene.base_dir)
    program = prepare(frame_of(scene, volume, transfer, resolve_arch("cube4")))
    return (build_dir(program, "verilator") / "Vcube4_bench").is_file()


def test_the_rtl_rung_reports_progress_and_announces_only_a_first_build():
    require("verilator")
    built = _built()
    fractions: list[float] = []
    started = _rtl_frame(lambda done, total, what=None: fractions.append(done / total))
    assert started == ([] if built else ["building RTL (Verilator), first run only"])
    assert fractions and fractions == sorted(fractions) and fractions[-1] == 1.0
    again = _rtl_frame(None)
    assert again == []  # built now: nothing announced
