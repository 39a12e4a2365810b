"""VIZARD II's compiled packet model (``models/machines/vizard2/packet_timing.py``), the
transaction rung's default timing: the machine's rules written again at packet, round
and page-run granularity, against the cycle rung.

Partly shared (``hwsim.studies.trade.independence``, ``vizard2``): the plan (positions,
leap ranges), the memory layout's sizes, ``FEEDBACK``/``FILL_WRITE``, the cache geometry
and the rays' termination steps (the functional rung's); the cache, the SDRAM timing,
the issue and the FIFO are the model's own.  Nothing in it was fitted.  The scenes below
are held out: the model was developed on the speed table's head scene (64^3 - 256^3)
and checked on random scenes of other seeds (benchmarks/README.md), never on these.
"""

from __future__ import annotations

import dataclasses

import pytest
import rungs

from hwsim.engine import DeadlockError
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from models.machines.vizard2.transaction import VizardTransaction
from models.transaction import timing_only, transaction_timing

pytestmark = pytest.mark.model

PACKET_MODEL = "packets, rounds and page runs (compiled)"

#: (phantom, volume size, image, projection, mode, lit, ERT threshold, leaping, cache sets,
#: pipelines, page policy, queue depth, pixel FIFO entries)
HELD_OUT = [
    ("head", 32, 30, "parallel", "composite", True, 1.0, True, (4, 4, 4), 1, "open", 2, 64),
    ("head", 40, 28, "perspective", "composite", False, 0.9, True, (4, 4, 4), 1, "open", 2, 64),
    ("ball", 24, 26, "parallel", "composite", False, 0.8, False, (2, 2, 2), 2, "open", 2, 8),
    ("ball", 32, 20, "perspective", "mip", False, 1.0, True, (8, 4, 2), 1, "closed", 2, 64),
    (
        "marschner-lobb",
        32,
        32,
        "parallel",
        "composite",
        True,
        0.95,
        True,
        (4, 4, 4),
        4,
        "open",
        3,
        64,
    ),  # fmt: skip
    (
        "marschner-lobb",
        16,
        18,
        "perspective",
        "composite",
        True,
        0.5,
        False,
        (2, 4, 8),
        1,
        "open",
        4,
        200,
    ),  # fmt: skip
    ("head", 48, 36, "parallel", "mip", False, 1.0, False, (4, 4, 4), 2, "open", 2, 1),
    ("head", 24, 24, "parallel", "composite", False, 0.7, True, (4, 4, 4), 1, "closed", 3, 64),
]


@pytest.fixture(scope="module")
def volumes():
    return {}


def frame_for(volumes, case):
    phantom, n, image, projection, mode, lit, ert, leap, sets, P, page, qd, fifo = case
    if (phantom, n) not in volumes:
        volumes[phantom, n] = make_phantom(phantom, size=n)
    volume = volumes[phantom, n]
    base = resolve_arch("vizard2")
    arch = dataclasses.replace(
        base,
        space_leaping=leap,
        pipelines=P,
        memory={**base.memory, "page_policy": page, "queue_depth": qd},
        buffers={**base.buffers, "cache_sets": list(sets), "pixel_fifo_entries": fifo},
    )
    scene = rungs.scene_of(
        41, -23, phantom=phantom, size=image, mode=mode, projection=projection, preset="auto",
        render={"early_termination": ert, "lighting": lit},
    )  # fmt: skip
    return frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)


@pytest.mark.parametrize("case", HELD_OUT, ids=lambda c: "-".join(map(str, c[:8])))
def test_held_out_scenes_within_the_contract(volumes, case):
    frame = frame_for(volumes, case)
    exact, model = render_cycle(frame), timing_only(frame)
    assert model.counters["transaction.granularity"] == PACKET_MODEL
    rungs.assert_within_contract(exact.cycles, model.cycles)
    stops = case[4] == "composite" and case[6] < 1.0
    if not stops:  # no clock decides which samples issue: lookups and fills by rule
        keys = ("frame.issued_samples", "cache.lookups", "cache.fills", "memory.bursts")
        rungs.assert_counters_equal(exact, model, keys)


def test_the_models_own_sdram_timing_decides_its_cycles(volumes, monkeypatch):
    """Evidence that can fail: the packet model given a slower SDRAM (t_rcd 2 -> 8) than
    the cycle rung's leaves the contract; the cycle rung does not read the model's."""
    frame = frame_for(volumes, HELD_OUT[0])
    exact = render_cycle(frame)
    init = VizardTransaction.__init__

    def slow_rows(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.memory = dataclasses.replace(
            self.memory, sdram=dataclasses.replace(self.memory.sdram, t_rcd=8)
        )

    monkeypatch.setattr(VizardTransaction, "__init__", slow_rows)
    slow = timing_only(frame)
    assert slow.counters["transaction.granularity"] == PACKET_MODEL
    assert slow.cycles > exact.cycles * (1 + rungs.CONTRACT)


def test_refused_frames_fall_back_to_the_shared_loop_labelled(volumes):
    frame = frame_for(volumes, (*HELD_OUT[0][:11], 1, 64))  # queue depth 1
    exact, model = render_cycle(frame), timing_only(frame)
    assert "queue_depth 1" in model.counters["transaction.packet_model_refused"]
    assert model.counters["transaction.granularity"] == "the cycle rung's ray loop, timing only"
    assert model.cycles == exact.cycles
    with pytest.raises(DeadlockError, match="pixel_bus.fifo: depth 0"):
        transaction_timing(frame_for(volumes, HELD_OUT[2]), pixel_fifo_depth=0)


def test_the_shared_loop_and_the_event_model_stay_reachable(volumes):
    frame = frame_for(volumes, HELD_OUT[1])
    loop = transaction_timing(frame, shared_loop=True)
    event = transaction_timing(frame, event_model=True)
    assert loop.counters["transaction.granularity"] == "the cycle rung's ray loop, timing only"
    assert event.counters["transaction.events"] > 0
    assert loop.cycles == render_cycle(frame).cycles
