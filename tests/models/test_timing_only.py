"""The transaction rung timing a frame without its image (issue 18's decision): the event
model alone, the same cycles and counters as with the image."""

from __future__ import annotations

import json

import numpy as np
import pytest
import rungs

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.sweep.runner import execute_run
from hwsim.studies.sweep.spec import parse_sweep, run_key
from hwsim.volumes import make_phantom
from models.frame import frame_of
from models.functional import render_functional
from models.transaction import render_transaction, termination_pass, timing_only

pytestmark = pytest.mark.model

#: Machines and scenes: those whose timing reads the rays' ends get early termination.
CASES = [
    ("cube4", {}),
    ("volumepro500", {}),
    ("em-cube", {}),
    ("volumepro1000", {"early_termination": 0.9}),
    ("vizard2", {"early_termination": 0.9}),
]


def _wall(counters: dict) -> dict:
    return {k: v for k, v in counters.items() if not k.endswith("_seconds")}


@pytest.mark.parametrize(("name", "render_keys"), CASES)
def test_timing_only_is_the_image_runs_timing(name, render_keys):
    volume = make_phantom("head", size=24)
    scene = rungs.scene_of(35, 25, size=24, render=render_keys)
    arch = resolve_arch(name)
    tf = resolve_transfer(scene.transfer, volume)
    full = render_transaction(frame_of(scene, volume, tf, arch))
    alone = timing_only(frame_of(scene, volume, tf, arch))
    assert alone.image is None
    assert alone.cycles == full.cycles
    full_counters = {k: v for k, v in _wall(full.counters).items() if k != "functional.saturated"}
    assert _wall(alone.counters) == full_counters


@pytest.mark.parametrize("name", ["volumepro1000", "vizard2"])
def test_the_unlit_pass_ends_the_rays_where_the_lit_render_does(name):
    volume = make_phantom("head", size=24)
    scene = rungs.scene_of(35, 25, size=24, render={"early_termination": 0.8})
    tf = resolve_transfer(scene.transfer, volume)
    frame = frame_of(scene, volume, tf, resolve_arch(name))
    lit = render_functional(frame).stopped
    assert lit is not None and np.any(lit < lit.max())  # some rays do end early
    assert np.array_equal(termination_pass(frame).stopped, lit)


def test_the_cli_writes_stats_only(tmp_path, capsys):
    args = ["render", "--phantom", "head:size=16", "--image", "16", "--arch", "volumepro500"]
    out = tmp_path / "t"
    assert main([*args, "--fidelity", "transaction", "--timing-only", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(("image", "stats"))) == [
        "stats.json"
    ]
    stats = json.loads((out / "stats.json").read_text())
    assert stats["image"] is None and stats["cycles"] > 0
    capsys.readouterr()
    assert main([*args, "--fidelity", "cycle", "--timing-only", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--timing-only" in err and "transaction" in err


def test_a_sweep_run_can_be_timed_without_its_image(tmp_path):
    data = {
        "schema": 1,
        "sweep": {
            "phantom": ["head:size=16"],
            "image": [16],
            "arch": ["volumepro500"],
            "fidelity": ["transaction"],
            "timing_only": [False, True],
        },
    }
    sweep = parse_sweep(data, source="s.toml", base_dir=tmp_path)
    image_run, timed_run = sweep.runs
    assert run_key(image_run) != run_key(timed_run)
    rows = [execute_run(r, run_key(r)) for r in (image_run, timed_run)]
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert rows[0]["image_sha256"] and rows[1]["image_sha256"] is None
    assert rows[0]["cycles"] == rows[1]["cycles"]
    with pytest.raises(InputError):
        parse_sweep({**data, "sweep": {**data["sweep"], "timing_only": ["yes"]}}, source="s.toml",
                    base_dir=tmp_path)  # fmt: skip
