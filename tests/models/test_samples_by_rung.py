"""A frame's ``samples`` are the same number on every rung of every machine.

``samples`` (and the ``samples_per_second`` and ``samples_per_cycle`` derived from them)
count the frame's samples as the functional rung does: every planned sample a live ray
passes through the crop box, cut planes and depth test.  What a machine issued, leaped or
fetched speculatively are counters (VIZARD II: ``frame.issued_samples``,
``frame.leaped_samples``, ``frame.composited_samples``).  Until this test the VIZARD II
cycle rung reported its composited samples (a third of the frame at 256^3) while its
functional and transaction rungs reported the frame's.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from hwsim.core.errors import HwsimError
from hwsim.run.fidelity import builtin_archs, render
from hwsim.spec.scene import CropSpec, CutPlane, VolumeSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from benchmarks.fingerprint import random_scene

RUNGS = ("functional", "transaction", "cycle")
#: What a random scene may add (a what-if where the machine lacks it: rendered with
#: ``extend=True``, refused the same way on every rung otherwise).
EXTRAS = (
    {},
    {"render": {"early_termination": 0.8}},
    {"crop": CropSpec(x=(2.0, 12.0), y=(1.0, 14.0), z=(0.0, 9.5))},
    {"cut_planes": (CutPlane(normal=(1.0, 0.3, 0.2), offset=0.5, thickness=4.0, falloff=2.0),)},
)


def _scene(rng: np.random.Generator, kind: str):
    scene, what = random_scene(rng)
    if kind == "axis":  # one every machine renders (Cube-1 looks along main axes, 16^3 at most)
        view = dataclasses.replace(scene.view, azimuth=0.0, elevation=0.0, projection="parallel")
        volume = dataclasses.replace(scene.volume, params=(("size", 12),))
        scene, what = scene.replace(view=view, volume=volume), f"{what} (axis view, 12^3)"
    elif kind == "leaping":  # empty blocks around the head: VIZARD II leaps, rays end early
        view = dataclasses.replace(scene.view, azimuth=30.0, elevation=20.0)
        volume = VolumeSpec(phantom="head", params=(("size", 24),))
        render_spec = dataclasses.replace(scene.render, mode="composite")
        scene = scene.replace(view=view, volume=volume, render=render_spec)
        what = f"head:24 {view.width}x{view.height} {view.projection} 30,20 composite"
    extra = EXTRAS[int(rng.integers(len(EXTRAS)))]
    if "render" in extra:
        render_spec = dataclasses.replace(scene.render, **extra["render"])
        return scene.replace(render=render_spec), f"{what} ert"
    return scene.replace(**extra), f"{what} {' '.join(extra) or 'plain'}"


@pytest.mark.parametrize("arch", sorted(builtin_archs()))
def test_samples_agree_on_every_rung(arch):
    rng = np.random.default_rng(sum(map(ord, arch)))
    for k, kind in enumerate(("axis", "leaping", "random")):
        scene, what = _scene(rng, kind)
        samples = {}
        for rung in RUNGS:
            try:
                samples[rung] = render(scene, fidelity=rung, arch=arch, extend=True).samples
            except HwsimError as exc:
                samples[rung] = type(exc).__name__
        assert len(set(samples.values())) == 1, f"{arch} {what}: {samples}"
        assert k or isinstance(samples["cycle"], int), f"{arch} {what}: {samples}"
