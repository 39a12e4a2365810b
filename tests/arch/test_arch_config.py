"""Architecture configs: built-ins load, cite their published rates, bad files are refused."""

from __future__ import annotations

import tomllib

import pytest

from hwsim.core.errors import InputError
from hwsim.run.fidelity import builtin_archs, check_scene_fits, resolve_arch
from hwsim.spec.arch import ORDERS, parse_arch
from hwsim.spec.scene import RenderSpec, Scene, ViewSpec

DESIGN_NAMES = {"cube4", "cube4-teramac", "em-cube", "volumepro500", "volumepro1000", "vizard2"}


def test_every_machine_of_the_design_is_built_in():
    archs = builtin_archs()
    assert DESIGN_NAMES <= set(archs)
    for cfg in archs.values():
        assert cfg.order in ORDERS and cfg.pipelines >= 1 and cfg.clock_hz > 0


@pytest.mark.parametrize(("name", "rate"), [("volumepro500", 500e6), ("volumepro1000", 1e9)])
def test_peak_rate_equals_the_published_sample_rate(name, rate):
    cfg = resolve_arch(name)
    assert cfg.peak_samples_per_second == rate == cfg.published["samples_per_second"]


def test_a_user_file_works_where_a_name_does(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text('schema = 1\n[pipeline]\norder = "shear-warp"\ncount = 2\nclock_hz = 50e6\n')
    cfg = resolve_arch(str(path))
    assert cfg.name == "mine" and cfg.peak_samples_per_second == 100e6


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('[pipeline]\norder = "zigzag"\ncount = 1\nclock_hz = 1', "pipeline.order"),
        ('[pipeline]\norder = "ray"\ncount = 0\nclock_hz = 1', "pipeline.count"),
        ('[pipeline]\norder = "ray"\ncount = 1\nclock_hz = nan', "pipeline.clock_hz"),
        (
            '[pipeline]\norder = "ray"\ncount = 1\nclock_hz = 1\n[limits]\nvoxel_bits = [9]',
            "limits.voxel_bits",
        ),
        ('[pipeline]\norder = "ray"\ncount = 1\nclock_hz = 1\nspeed = 2', "pipeline.speed"),
        ("schema = 1", "pipeline"),
    ],
)
def test_bad_arch_files_name_the_key(text, key):
    with pytest.raises(InputError, match=rf"a\.toml: {key}[:\[]"):
        parse_arch(tomllib.loads(text), source="a.toml", name="a")


def test_unknown_name_lists_the_built_ins():
    with pytest.raises(InputError, match="volumepro500"):
        resolve_arch("cray-1")


def test_perspective_is_refused_on_a_parallel_only_machine():
    scene = Scene(view=ViewSpec(projection="perspective"))
    with pytest.raises(InputError, match="parallel projection only"):
        check_scene_fits(scene, resolve_arch("volumepro500"))
    check_scene_fits(scene, resolve_arch("volumepro1000"))  # VP1000 renders perspective
    with pytest.raises(InputError, match="render.supersampling"):
        check_scene_fits(Scene(render=RenderSpec(supersampling=0.5)), resolve_arch("volumepro500"))


def test_a_machine_refuses_more_cut_planes_than_it_has():
    from hwsim.spec.scene import CutPlane

    two = Scene(cut_planes=(CutPlane(), CutPlane(normal=(1.0, 0.0, 0.0))))
    with pytest.raises(InputError, match=r"volumepro500 has no 2 cut plane\(s\) \(cut_planes: 1"):
        check_scene_fits(two, resolve_arch("volumepro500"))
    check_scene_fits(two, resolve_arch("volumepro1000"))  # up to 4 [V]
    what_if = check_scene_fits(two, resolve_arch("volumepro500"), extend=True)
    assert [e.feature for e in what_if] == ["cut_planes"]


def test_a_bad_memory_table_is_refused_when_the_file_loads(tmp_path):
    from hwsim.spec.arch import load_arch_file

    path = tmp_path / "bad.toml"
    path.write_text(
        'schema = 1\n[pipeline]\norder = "shear-warp"\ncount = 4\nclock_hz = 1e8\n'
        "[memory]\nbanks = 0\n"
    )
    with pytest.raises(InputError, match=r"bad\.toml.*memory\.banks"):
        load_arch_file(path)


def test_formats_take_toml_dotted_keys_as_well_as_quoted_ones():
    from models.datapath import Datapath

    for text in ('"interp.weight_bits" = 9', "interp.weight_bits = 9"):
        data = tomllib.loads(
            'schema = 1\n[pipeline]\norder = "shear-warp"\ncount = 4\nclock_hz = 1e8\n'
            f"[formats]\n{text}\n"
        )
        arch = parse_arch(data, source="x.toml", name="x")
        assert Datapath.from_arch(arch, 12).interp.weight_bits == 9
