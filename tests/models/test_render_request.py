"""One render request (issue 31): render's options as a frozen RenderRequest, refused
when it is made, and a table choosing how the frame is executed."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import rungs

from hwsim.core.errors import InputError
from hwsim.run.fidelity import choose_execution, render
from hwsim.run.render_request import MAX_WORKERS, RenderRequest
from hwsim.volumes import make_phantom

pytestmark = pytest.mark.model


@pytest.mark.parametrize(
    ("options", "key", "text"),
    [
        ({"fidelity": "exact"}, "--fidelity", "unknown fidelity 'exact'"),
        ({"steady_state": True}, "steady_state", "back-to-back frames"),
        ({"fidelity": "cycle", "timing_only": True}, "--timing-only", "without its image"),
        ({"fidelity": "functional", "elaborate_all": True}, "elaborate_all", "elaborates"),
        ({"fidelity": "transaction", "trace": "x.vcd"}, "--trace", "a waveform"),
        ({"fidelity": "cycle", "simulator": "icarus"}, "--simulator", "rtl rung only"),
        ({"fidelity": "transaction", "workers": 2}, "--workers", "in one process"),
        ({"fidelity": "cycle", "workers": 2, "scheduler": "tcp://x"}, "--workers", "not both"),
        ({"fidelity": "cycle", "workers": MAX_WORKERS + 1}, "--workers", "out of range"),
        ({"fidelity": "cycle", "workers": 2, "bands": 0}, "--bands", "out of range"),
        ({"fidelity": "cycle", "workers": 2, "steady_state": True}, "--steady-state", "one"),
    ],
)
def test_a_request_no_rung_renders_is_refused_when_made(options, key, text):
    with pytest.raises(InputError, match=text) as caught:
        RenderRequest(**options)
    assert caught.value.key == key
    with pytest.raises(InputError, match=text):  # render's keywords are the same request
        render(rungs.scene_of(size=8), **options)


def test_a_request_is_frozen_and_revalidated_when_replaced():
    request = RenderRequest(fidelity="cycle", arch="cube4")
    with pytest.raises(dataclasses.FrozenInstanceError):
        request.fidelity = "rtl"  # type: ignore[misc]
    assert RenderRequest.of(request) is request
    assert RenderRequest.of(request, workers=2).split
    with pytest.raises(InputError, match="--timing-only"):
        RenderRequest.of(request, timing_only=True)
    assert RenderRequest().machine is None and RenderRequest(fidelity="cycle").machine


@pytest.mark.parametrize(
    ("options", "bricked", "name"),
    [
        ({}, False, "golden"),
        ({"arch": "cube4"}, True, "golden"),  # golden renders a supervolume whole
        ({"fidelity": "transaction", "timing_only": True}, False, "timing-only"),
        ({"fidelity": "cycle", "workers": 2}, False, "split"),
        ({"fidelity": "cycle"}, True, "bricks"),
        ({"fidelity": "rtl"}, False, "one process"),
    ],
)
def test_the_first_execution_that_applies_runs_the_frame(options, bricked, name):
    job = SimpleNamespace(request=RenderRequest(**options), bricked=bricked)
    assert choose_execution(job)[0] == name  # type: ignore[arg-type]


@pytest.mark.parametrize("fidelity", ["golden", "transaction", "cycle"])
def test_a_request_renders_what_its_keywords_do(fidelity):
    scene, volume = rungs.scene_of(size=12), make_phantom("head", size=12)
    keywords = {"fidelity": fidelity, "arch": "cube4", "volume": volume}
    by_keywords = render(scene, **keywords)
    by_request = render(scene, RenderRequest(**keywords))
    assert np.array_equal(by_keywords.image, by_request.image)
    assert by_keywords.cycles == by_request.cycles
    wall = {k for k in by_keywords.counters if k.endswith("_seconds")}
    assert {k: v for k, v in by_keywords.counters.items() if k not in wall} == {
        k: v for k, v in by_request.counters.items() if k not in wall
    }
