"""The scene format: defaults, built-ins, and one-line errors naming file, key and range."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scene_text import error_of, parse

from hwsim.core.errors import InputError
from hwsim.spec.overrides import SceneFlags, apply_overrides
from hwsim.spec.scene import (
    DEFAULT_SCENE,
    MODES,
    builtin_scenes,
    load_scene,
    parse_scene,
)


def test_empty_file_gives_the_documented_defaults():
    scene = parse("")
    assert scene.volume.phantom == "head"
    assert scene.render.mode == "composite"
    assert scene.view.width == scene.view.height == 256
    assert scene.render.early_termination == 1.0
    assert len(scene.lights) == 1


def test_every_builtin_scene_loads_and_the_default_exists():
    names = builtin_scenes()
    assert DEFAULT_SCENE in names
    for name in names:
        scene = load_scene(name)
        assert scene.name == name
        assert scene.render.mode in MODES
    assert load_scene(None).name == DEFAULT_SCENE


def test_full_scene_round_trips_every_section():
    scene = parse("""
        schema = 1
        [volume]
        path = "ct.nrrd"
        spacing = [1.5, 0.9, 0.9]
        [transfer]
        points = [[0, 0, 0, 0, 0], [100, 1, 0.5, 0.25, 0.8]]
        gradient_opacity = [[0, 0.2], [50, 1.0]]
        order = "pre"
        [view]
        azimuth = -45
        elevation = 90
        projection = "perspective"
        fov = 40
        width = 64
        height = 32
        [[lights]]
        direction = [0, 0, 1]
        intensity = 0.5
        [[lights]]
        direction = [1, 0, 0]
        space = "world"
        [material]
        shininess = 128
        [render]
        mode = "iso"
        iso_value = 40
        supersampling = 2
        sample_spacing = 0.5
        early_termination = 0.95
        gradient = "sample"
        [crop]
        x = [10, 20]
        invert = true
        mode = "cross"
        [[cut_planes]]
        normal = [0, 1, 0]
        thickness = 4
        falloff = 2
    """)
    assert scene.volume.spacing == (1.5, 0.9, 0.9)
    assert scene.transfer.order == "pre" and scene.transfer.preset is None
    assert scene.view.projection == "perspective" and scene.view.elevation == 90
    assert [light.space for light in scene.lights] == ["view", "world"]
    assert scene.render.step == 0.25
    assert scene.crop is not None and scene.crop.x == (10, 20) and scene.crop.y is None
    assert scene.crop.mode == "cross" and scene.crop.slabs_needed == 2
    assert scene.cut_planes[0].thickness == 4
    assert scene.to_dict()["schema"] == 1


@pytest.mark.parametrize(
    ("text", "key", "allowed"),
    [
        ("[view]\nazimuth = 400", "view.azimuth", "-360 .. 360"),
        ("[view]\nelevation = 'up'", "view.elevation", "-90 .. 90"),
        ("[view]\nwidth = 0", "view.width", "1 .. 4096"),
        ("[view]\nheight = 2.5", "view.height", "1 .. 4096"),
        ("[render]\nmode = 'dvr'", "render.mode", "composite, mip, minip, xray, iso"),
        ("[render]\nsample_spacing = 0", "render.sample_spacing", "0.0625 .. 16"),
        ("[render]\nsupersampling = 64", "render.supersampling", "0.125 .. 16"),
        ("[render]\nearly_termination = 0", "render.early_termination", "0 (exclusive) .. 1"),
        ("[render]\nmode = 'mip'\ncolour = 1", "render.colour", "unknown key"),
        ("[volume]\nphantom = 'ball'\npath = 'x.nrrd'", "volume.path", "exactly one"),
        ("[transfer]\npoints = [[0, 0, 0, 0, 2]]", "transfer.points[0][4]", "0 .. 1"),
        (
            "[transfer]\npoints = [[5, 0, 0, 0, 0], [1, 0, 0, 0, 0]]",
            "transfer.points[1][0]",
            "ascending",
        ),
        ("[transfer]\npreset = 'bone'", "transfer.preset", "auto, ct, mr, ramp"),
        ("[[lights]]\ndirection = [0, 0, 0]", "lights[0].direction", "non-zero"),
        ("[crop]\nx = [5, 1]", "crop.x", "lo <= hi"),
        ("[crop]\nmode = 'slab'", "crop.mode", "subvolume, cross, fence"),
        ("schema = 2", "schema", "1"),
        ("[material]\nshininess = 0.5", "material.shininess", "1 .. 1024"),
    ],
)
def test_bad_values_name_the_key_and_the_allowed_range(text, key, allowed):
    message = error_of(text)
    assert f": {key}:" in message
    assert allowed in message


def test_nan_and_inf_are_refused():
    assert "out of range, got nan" in error_of("[view]\nazimuth = nan")
    assert "out of range, got inf (allowed: a finite number)" in error_of(
        "[render]\niso_value = inf"
    )


def test_malformed_toml_names_the_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[view\nazimuth = 1\n")
    with pytest.raises(InputError, match=r"bad\.toml: malformed TOML"):
        load_scene(bad)
    with pytest.raises(InputError, match="file not found"):
        load_scene(tmp_path / "missing.toml")
    with pytest.raises(InputError, match="unknown built-in scene 'nope'"):
        load_scene("nope")


SECTION_KEYS = {
    "view": ["azimuth", "elevation", "fov", "distance", "zoom", "width", "height", "projection"],
    "render": [
        "mode",
        "sample_spacing",
        "supersampling",
        "early_termination",
        "iso_value",
        "lighting",
        "interpolation",
    ],
    "material": ["ambient", "diffuse", "specular", "shininess"],
}
VALUES = st.one_of(
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.booleans(),
    st.lists(st.integers(), max_size=3),
)


@settings(max_examples=300, deadline=None)
@given(section=st.sampled_from(sorted(SECTION_KEYS)), data=st.data(), value=VALUES)
def test_any_value_is_accepted_or_refused_with_input_error(section, data, value):
    key = data.draw(st.sampled_from(SECTION_KEYS[section]))
    try:
        scene = parse_scene({section: {key: value}}, source="t.toml")
    except InputError as exc:
        assert f"t.toml: {section}.{key}:" in str(exc)
    else:  # accepted values are stored as given and are finite
        stored = getattr(getattr(scene, section), key)
        assert stored == value or stored == float(value)


@pytest.mark.parametrize(
    ("flags", "text"),
    [
        (SceneFlags(image="0"), "[view]\nwidth = 0"),
        (SceneFlags(image="64x5000"), "[view]\nheight = 5000"),
        (SceneFlags(view="400,0"), "[view]\nazimuth = 400"),
        (SceneFlags(view="0,-91"), "[view]\nelevation = -91"),
        (SceneFlags(volume="x.raw", shape="0,8,8"), "[volume]\npath = 'x.raw'\nshape = [0, 8, 8]"),
        (SceneFlags(mode="dvr"), "[render]\nmode = 'dvr'"),
    ],
)
def test_a_flag_and_the_key_it_overrides_share_one_range(flags, text):
    """Flags are checked by the scene file's model: the same range, the same wording."""
    with pytest.raises(InputError) as flag:
        apply_overrides(load_scene("head"), flags)
    with pytest.raises(InputError) as key:
        parse(text)
    assert flag.value.allowed == key.value.allowed and flag.value.allowed
    assert flag.value.message.split(",")[0] == key.value.message.split(",")[0]


def _without_none(value):
    if isinstance(value, dict):
        return {k: _without_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [_without_none(v) for v in value]
    return value


@pytest.mark.parametrize("name", sorted(builtin_scenes()))
def test_a_scene_dict_parses_back_to_the_scene(name):
    """stats.json's "scene" (``to_dict``, its None values left out as ``hwsim report``
    reads it) is a scene file that loads to the same Scene, [classification] included."""
    scene = load_scene(name)
    data = {k: v for k, v in _without_none(scene.to_dict()).items() if k != "source"}
    assert parse_scene(data, source=scene.source, name=name) == scene
