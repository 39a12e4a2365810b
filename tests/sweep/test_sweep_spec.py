"""Sweep files: the product of the lists, one-line errors, keys that change with every input."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from hwsim.core.errors import InputError
from hwsim.studies.sweep import build_run, parse_sweep, run_key
from hwsim.studies.sweep import spec as spec_module

REPO = Path(__file__).resolve().parents[2]


def sweep(table: dict, tmp_path) -> spec_module.Sweep:
    return parse_sweep({"sweep": table}, source="s.toml", base_dir=tmp_path)


def test_runs_are_the_product_of_the_lists_in_parameter_order(tmp_path):
    s = sweep(
        {
            "pipelines": [1, 2, 4],
            "arch": ["cube4", "volumepro500"],
            "phantom": ["ball:size=16"],
            "image": [16, [24, 12]],
        },
        tmp_path,
    )
    assert len(s.runs) == 3 * 2 * 2
    first = s.runs[0].values
    assert list(first) == ["phantom", "arch", "image", "pipelines"]
    assert first == {"phantom": "ball:size=16", "arch": "cube4", "image": [16, 16], "pipelines": 1}
    assert s.runs[-1].values["image"] == [24, 12]


def test_build_run_applies_scene_parameters_and_arch_overrides(tmp_path):
    s = sweep(
        {
            "arch": ["volumepro1000"],
            "phantom": ["head:size=24"],
            "mode": ["mip"],
            "view": [[90, -10]],
            "image": [[40, 30]],
            "pipelines": [3],
            "clock_hz": [50e6],
            "formats": {"interp": {"weight_bits": [6]}},
        },
        tmp_path,
    )
    scene, arch, fidelity, overrides = build_run(s.runs[0])
    assert scene.volume.phantom == "head" and dict(scene.volume.params) == {"size": 24}
    assert scene.render.mode == "mip"
    assert (scene.view.azimuth, scene.view.elevation) == (90.0, -10.0)
    assert (scene.view.width, scene.view.height) == (40, 30)
    assert fidelity == "functional"
    assert arch.name == "volumepro1000" and arch.pipelines == 3 and arch.clock_hz == 50e6
    assert arch.formats["interp.weight_bits"] == 6
    assert overrides == {"pipelines": 3, "clock_hz": 50e6, "formats.interp.weight_bits": 6}


def test_golden_without_arch_is_the_ideal_ray_caster(tmp_path):
    s = sweep({"fidelity": ["golden"], "phantom": ["ball:size=16"]}, tmp_path)
    _, arch, fidelity, _ = build_run(s.runs[0])
    assert fidelity == "golden" and arch is None


def test_key_changes_with_scene_arch_override_fidelity_and_code(tmp_path, monkeypatch):
    base = {"arch": ["cube4"], "phantom": ["ball:size=16"], "fidelity": ["functional"]}
    key = run_key(sweep(base, tmp_path).runs[0])
    assert run_key(sweep(base, tmp_path).runs[0]) == key  # stable
    variants = [
        {**base, "phantom": ["ball:size=17"]},
        {**base, "arch": ["em-cube"]},
        {**base, "pipelines": [2]},
        {**base, "fidelity": ["golden"]},
        {**base, "view": [[10, 0]]},
    ]
    keys = {run_key(sweep(v, tmp_path).runs[0]) for v in variants}
    assert key not in keys and len(keys) == len(variants)
    monkeypatch.setattr(spec_module, "code_version", lambda: "0.0.0+other")
    assert run_key(sweep(base, tmp_path).runs[0]) != key


def test_an_override_to_the_default_value_is_the_same_machine(tmp_path):
    """pipelines = 4 on a 4-pipeline machine is recorded as an override, so the key differs:
    the row says what the user asked for."""
    a = run_key(sweep({"arch": ["cube4"]}, tmp_path).runs[0])
    b = run_key(sweep({"arch": ["cube4"], "pipelines": [4]}, tmp_path).runs[0])
    assert a != b
    _, arch_a, _, _ = build_run(sweep({"arch": ["cube4"]}, tmp_path).runs[0])
    _, arch_b, _, _ = build_run(sweep({"arch": ["cube4"], "pipelines": [4]}, tmp_path).runs[0])
    assert dataclasses.asdict(arch_a) == dataclasses.asdict(arch_b)


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        (
            {"pipelines": [1, 0]},
            "s.toml: sweep.pipelines[1]: out of range, got 0 (allowed: 1 .. 4096)",
        ),
        (
            {"fidelity": ["fast"]},
            "s.toml: sweep.fidelity[0]: unknown value 'fast' (allowed: golden, functional,",
        ),
        ({"arch": ["vp9"]}, "s.toml: sweep.arch[0]: unknown architecture 'vp9'"),
        ({"colour": [1]}, "s.toml: sweep.colour: unknown key 'colour' (allowed: scene, phantom,"),
        ({"mode": "mip"}, "s.toml: sweep.mode: must be an array, got 'mip'"),
        ({"mode": []}, "s.toml: sweep.mode: must be an array of length >= 1"),
        (
            {"view": [[0, 91]]},
            "s.toml: sweep.view[0][1]: out of range, got 91 (allowed: -90 .. 90)",
        ),
        ({"image": [0]}, "s.toml: sweep.image[0]: out of range, got 0 (allowed: 1 .. 4096)"),
        ({"image": [[16, 16, 16]]}, "s.toml: sweep.image[0]: must be an array of length <= 2"),
        ({"phantom": ["cube"]}, "s.toml: sweep.phantom[0]: unknown phantom 'cube'"),
        (
            {"volume": ["missing.nrrd"]},
            "s.toml: sweep.volume[0]: volume 'missing.nrrd': file not found",
        ),
        (
            {"formats": {"interp": {"nope": [1]}}},
            "s.toml: sweep.formats.interp.nope: unknown format key",
        ),
        (
            {"formats": {"interp": {"weight_bits": [40]}}},
            "s.toml: sweep.formats.interp.weight_bits: invalid format",
        ),
        ({"phantom": ["ball"], "volume": ["x"]}, "s.toml: sweep.volume"),
    ],
)
def test_bad_sweep_files_fail_in_one_line_naming_file_and_key(tmp_path, table, needle):
    (tmp_path / "x").write_text("")
    with pytest.raises(InputError) as info:
        sweep(table, tmp_path)
    text = str(info.value)
    assert "\n" not in text and text.startswith(needle), text


def test_missing_sweep_table_and_wrong_schema(tmp_path):
    with pytest.raises(InputError, match="s.toml: sweep: is required"):
        parse_sweep({}, source="s.toml", base_dir=tmp_path)
    with pytest.raises(InputError, match=r"s.toml: schema: unknown value 2 \(allowed: 1\)"):
        parse_sweep({"schema": 2, "sweep": {}}, source="s.toml", base_dir=tmp_path)


def test_an_arch_file_beside_the_sweep_file_is_found_and_its_errors_name_it(tmp_path):
    good = (REPO / "models" / "machines" / "cube4" / "cube4.toml").read_text()
    (tmp_path / "mine.toml").write_text(good.replace('name = "cube4"', 'name = "mine"'))
    _, arch, _, _ = build_run(sweep({"arch": ["mine.toml"]}, tmp_path).runs[0])
    assert arch.name == "mine"
    (tmp_path / "bad.toml").write_text(good.replace("count = 4", "count = 0"))
    with pytest.raises(InputError) as info:
        sweep({"arch": ["bad.toml"]}, tmp_path)
    line = f"{re.escape(str(tmp_path / 'bad.toml'))}: pipeline.count: "
    assert re.match(line + "(0 is out of range|out of range, got 0)", str(info.value))
