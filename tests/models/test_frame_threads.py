"""A frame's compiled composite stage on several threads (``HWSIM_THREADS``): the same
bits as on one (issue 18: use both cores where a frame allows)."""

from __future__ import annotations

import numpy as np
import pytest
import rungs

from hwsim.core import threads as frame_threads_module
from hwsim.core.errors import InputError
from hwsim.run.fidelity import render, resolve_arch
from hwsim.volumes import make_phantom

pytestmark = pytest.mark.model


@pytest.mark.parametrize("name", ["volumepro500", "volumepro1000", "cube4"])
def test_threads_render_the_same_bits(monkeypatch, name):
    volume = make_phantom("head", size=128)
    scene = rungs.scene_of(35, 25, size=128, render={"early_termination": 0.9})
    if name != "volumepro1000":  # the others had no early termination
        scene = rungs.scene_of(35, 25, size=128)
    arch = resolve_arch(name)
    runs = {}
    for threads in ("1", "2", "3"):
        monkeypatch.setenv(frame_threads_module.THREADS_ENV_VAR, threads)
        runs[threads] = render(scene, fidelity="functional", arch=arch, volume=volume)
    one = runs["1"]
    assert {2, 3} <= set(frame_threads_module._POOLS)  # steps were big enough to be cut into runs
    for threads in ("2", "3"):
        run = runs[threads]
        assert np.array_equal(run.image, one.image), threads
        assert (run.samples, run.rays, run.cycles) == (one.samples, one.rays, one.cycles)
        assert run.counters == one.counters


@pytest.mark.parametrize("text", ["0", "two", "-1", "1000"])
def test_a_bad_thread_count_is_refused_naming_the_variable(monkeypatch, text):
    monkeypatch.setenv(frame_threads_module.THREADS_ENV_VAR, text)
    with pytest.raises(InputError) as info:
        frame_threads_module.frame_threads()
    assert info.value.key == "HWSIM_THREADS"
