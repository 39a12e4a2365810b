"""``hwsim warm``: which renders warm the kernel cache, and that one runs on a tiny frame.

The compile notice itself (shown exactly when the cache is cold) is tested in
test_progress.py; running every warming render here would only repeat other tests."""

from __future__ import annotations

import pytest

from hwsim.cli.warm import TINY, _tiny, warm_jobs
from hwsim.run.fidelity import builtin_archs, machine_rungs, render
from hwsim.spec.scene import builtin_scenes, load_scene

pytestmark = pytest.mark.system


def test_warm_renders_every_scene_golden_and_every_machine_at_its_compiled_rungs():
    jobs = warm_jobs()
    assert {(s, None) for s in builtin_scenes()} <= {(s, a) for s, f, a in jobs if f == "golden"}
    for name, arch in builtin_archs().items():
        wanted = {r for r in ("functional", "cycle") if r in machine_rungs(arch)}
        assert "functional" in wanted
        assert {f for _, f, a in jobs if a == name} == wanted, name


def test_a_warming_frame_is_tiny_and_renders():
    scene = _tiny(load_scene("head"))
    assert (scene.view.width, scene.view.height) == (TINY, TINY)
    assert dict(scene.volume.params)["size"] == TINY
    run = render(scene, fidelity="cycle", arch="volumepro500")
    assert run.image.shape[:2] == (TINY, TINY) and run.cycles > 0
