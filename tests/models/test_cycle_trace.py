"""The Cube-4 waveform: each interpolator's ``i__valid`` is high exactly on its sample cycles."""

from __future__ import annotations

import dataclasses
import re

import pytest

from hwsim.run.fidelity import render
from hwsim.spec.scene import VolumeSpec, load_scene

pytestmark = pytest.mark.model


def high_cycles(vcd: str) -> dict[str, int]:
    """Cycles each 1-bit signal spends high, by scope path and name."""
    ids, scope = {}, []
    for line in vcd.split("$enddefinitions $end")[0].splitlines():
        if line.startswith("$scope"):
            scope.append(line.split()[2])
        elif line.startswith("$upscope"):
            scope.pop()
        elif line.startswith("$var wire 1 "):
            _, _, _, ident, name, _ = line.split()
            ids[ident] = "/".join([*scope, name])
    high, since, now = dict.fromkeys(ids.values(), 0), {}, 0
    for line in vcd.split("$enddefinitions $end")[1].splitlines():
        if line.startswith("#"):
            now = int(line[1:])
        elif m := re.fullmatch(r"([01])(\S+)", line):
            name = ids.get(m.group(2))
            if name is None:
                continue
            if m.group(1) == "1":
                since.setdefault(name, now)
            elif name in since:
                high[name] += now - since.pop(name)
    return high


def test_interpolator_valid_stays_high_through_back_to_back_samples(tmp_path):
    scene = load_scene("head").replace(
        volume=VolumeSpec(phantom="head", params=(("size", 12),)),
    )
    view = dataclasses.replace(scene.view, azimuth=0.0, elevation=0.0, width=12, height=12)
    scene = scene.replace(view=view)
    vcd = tmp_path / "t.vcd"
    run = render(scene, fidelity="cycle", arch="cube4", trace=vcd)
    high = high_cycles(vcd.read_text())
    lanes = {k: v for k, v in high.items() if k.endswith("interp/i__valid")}
    assert len(lanes) == 4
    # Axis-aligned: each pipeline takes at most one sample per clock, so the high cycles
    # over all interpolators are the frame's samples.
    assert sum(lanes.values()) == run.samples
