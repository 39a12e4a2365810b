"""The lean event loop (models/machines/volumepro/event_loop.py) keeps SimPy's order: the
same traces as ``simpy.Environment`` on random process schedules (same-cycle ties
included); and the VolumePro-family event model's cycles and counters are the same on
SimPy (``events="simpy"``, the reference), on the lean loop and compiled
(models/machines/volumepro/pipeline_kernel.py)."""

from __future__ import annotations

import itertools

import pytest
import rungs
import simpy
from hypothesis import given, reject, settings
from hypothesis import strategies as st

from hwsim.core.errors import InputError
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of
from models.machines.volumepro import event_loop
from models.machines.volumepro.event_loop import EventLoop
from models.transaction import termination_pass, transaction_model

pytestmark = pytest.mark.model


def _trace(env, plans):
    """Processes that wait random delays (0 included: same-cycle ties), trigger and wait
    on shared events, and log each step; returns the log."""
    log = []
    gates = [env.event() for _ in range(3)]

    def proc(pid, steps):
        for k, (kind, arg) in enumerate(steps):
            log.append((env.now, pid, k))
            if kind == "wait":
                yield env.timeout(arg)
            elif kind == "open":
                gate = gates[arg]
                if not gate.triggered:
                    gate.callbacks.append(lambda _e, pid=pid: log.append(("cb", env.now, pid)))
                    gate.succeed()
            elif kind == "gate":
                yield gates[arg]  # processed already: goes on at once
            else:
                yield env.event().succeed()

    for pid, steps in enumerate(plans):
        env.process(proc(pid, steps))
    env.run()
    return log


_step = st.one_of(
    st.tuples(st.just("wait"), st.integers(0, 3)),
    st.tuples(st.just("open"), st.integers(0, 2)),
    st.tuples(st.just("gate"), st.integers(0, 2)),
    st.tuples(st.just("now"), st.just(0)),
)
_plans = st.lists(st.lists(_step, max_size=8), min_size=1, max_size=4)


def _opened_last(plans):
    """A gate nobody opens would leave its waiters hanging alike in both; open every gate
    at the end of a last process so each run ends the same way."""
    return [*plans, [("wait", 4), ("open", 0), ("open", 1), ("open", 2)]]


@settings(max_examples=300, deadline=None)
@given(_plans)
def test_random_schedules_run_in_simpys_order(plans):
    plans = _opened_last(plans)
    assert _trace(EventLoop(), plans) == _trace(simpy.Environment(), plans)


class _LifoLoop(EventLoop):
    """A broken loop: same-cycle ties the other way round."""

    def __init__(self):
        super().__init__()
        self._seq = itertools.count(0, -1)


def test_a_loop_breaking_ties_the_other_way_is_caught():
    plans = _opened_last([[("wait", 1), ("wait", 1)], [("wait", 2), ("wait", 0)]])
    assert _trace(_LifoLoop(), plans) != _trace(simpy.Environment(), plans)
    assert event_loop._URGENT < event_loop._NORMAL  # a process starts before the rest


def _results(name, az, el, size, image, options, projection="parallel"):
    volume = make_phantom("head", size=size)
    scene = rungs.scene_of(
        az, el, size=image, projection=projection, render={"early_termination": 0.9}
    )
    try:
        plan = make_plan(scene, volume, resolve_arch(name).order)
    except InputError:  # a view the plan refuses (e.g. an eye inside the volume)
        reject()
    tf = resolve_transfer(scene.transfer, volume)
    frame = frame_of(scene, volume, tf, resolve_arch(name), plan)
    stopped = termination_pass(frame).stopped if name == "volumepro1000" else None
    out = []
    for events in ("simpy", "generators", "compiled"):
        model = transaction_model(frame, stopped=stopped, events=events, **options)
        try:
            t = model.run()
        except Exception as e:  # the same error either way
            out.append((type(e).__name__, str(e)))
            continue
        wall = {k: v for k, v in t.counters.items() if not k.endswith("_seconds")}
        out.append((t.cycles, wall))
    return out


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(["volumepro1000", "volumepro500", "em-cube"]),
    az=st.floats(-180, 180),
    el=st.floats(-80, 80),
    size=st.sampled_from([8, 12, 16, 24]),
    image=st.sampled_from([8, 16, 24, 40]),
    depth=st.sampled_from([None, 0, 1, 2, 5, 16]),
    groups=st.sampled_from([1, 3, 8, 32]),
    steady=st.booleans(),
    projection=st.sampled_from(["parallel", "perspective"]),
)
def test_the_event_model_is_the_same_on_simpy(
    name, az, el, size, image, depth, groups, steady, projection
):
    options = {"groups": groups, "steady_state": steady}
    if depth is not None:
        options["pixel_fifo_depth"] = depth
    ref, lean, compiled = _results(name, az, el, size, image, options, projection)
    assert lean == ref
    assert compiled == ref
