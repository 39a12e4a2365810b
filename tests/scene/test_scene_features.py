"""``[classification]`` and ``[geometry]`` scene sections and the arch feature keys:
valid specs parse into the documented values, bad ones fail in one line naming the
file, the key and the allowed range."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scene_text import error_of, parse

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.arch import parse_arch
from hwsim.spec.scene import parse_scene

pytestmark = pytest.mark.golden

LUT = "[[classification.luts]]\npoints = [[0, 0, 0, 0, 0], [1, 1, 1, 1, 1]]\n"
SMALL = LUT + "entries = 256\n"


def test_full_classification_section_parses():
    scene = parse(
        """
        [transfer]
        order = "pre"
        [[classification.fields]]
        name = "density"
        lsb = 4
        bits = 12
        [[classification.fields]]
        name = "tag"
        bits = 4
        [[classification.luts]]
        field = "density"
        points = [[0, 0, 0, 0, 0], [4095, 1, 1, 1, 1]]
        [[classification.luts]]
        preset = "ct"
        [[classification.luts]]
        field = "tag"
        entries = 256
        points = [[0, 0, 0, 0, 0], [15, 1, 1, 1, 1]]
        [classification.combine]
        leaf0 = { rgb = "max", alpha = "add" }
        final = "mul_b_alpha"
        """
    )
    c = scene.classification
    assert [f.name for f in c.fields] == ["density", "tag"] and c.fields[0].lsb == 4
    assert [lut.entries for lut in c.luts] == [4096, 4096, 256]
    assert c.luts[1].field == "value" and c.luts[1].transfer.preset == "ct"
    assert c.leaf0.ops == ("max", "add") and c.final.ops == ("mul_b_alpha", "mul_b_alpha")
    assert c.leaf1.ops == ("a", "a")
    assert scene.transfer.order == "pre"
    assert scene.to_dict()["classification"]["luts"][0]["field"] == "density"


def test_geometry_section_parses():
    scene = parse(
        """
        [geometry]
        depth_test = ">="
        [[geometry.spheres]]
        center = [1, 2, 3]
        radius = 4
        color = [0.1, 0.2, 0.3]
        [[geometry.boxes]]
        lo = [0, 0, 0]
        hi = [1, 2, 3]
        """
    )
    g = scene.geometry
    assert g.depth_test == ">=" and g.spheres[0].radius == 4.0 and g.boxes[0].hi == (1, 2, 3)
    assert parse("").geometry is None and parse("").classification is None


C = "[classification.combine]\n"
F = "[[classification.fields]]\nname='d'\n"
G = "[geometry]\n"
BALL = "[[geometry.spheres]]\ncenter = [0, 0, 0]\n"
BAD = [
    ("[classification]\n", "classification.luts", "is required"),
    (LUT * 5 + C + "leaf0='a'\nleaf1='a'\nfinal='a'", "classification.luts", "1 .. 4"),
    (
        LUT.replace("points", "entries = 1024\npoints"),
        "classification.luts[0].entries",
        "256, 4096",
    ),
    (
        LUT * 3 + C + "leaf0='add'\nfinal='add'",
        "classification.luts",
        "on lut0/lut1 or on lut2/lut3",
    ),
    (LUT * 2, "classification.combine.leaf0", "is required"),
    (LUT * 2 + SMALL + C + "leaf0='add'", "classification.combine.final", "is required"),
    (LUT * 2 + C + "leaf0='mul_b_alpha'", "classification.combine.leaf0", "mul8"),
    (LUT * 2 + C + "leaf0={rgb='nand'}", "classification.combine.leaf0.rgb", "xor"),
    (LUT * 2 + C + "leaf0=3", "classification.combine.leaf0", "a string or a table"),
    (LUT * 2 + C + "leaf0='add'\nleaf2='add'", "classification.combine.leaf2", "unknown key"),
    (F + "bits=3\n" + LUT, "classification.fields[0].bits", "4 .. 16"),
    (F + "bits=17\n" + LUT, "classification.fields[0].bits", "4 .. 16"),
    (F + "bits=12\nlsb=24\n" + LUT, "classification.fields[0].lsb", "0 .. 20"),
    (F.replace("'d'", "'value'") + "bits=8\n" + LUT, "classification.fields[0].name", "new name"),
    ((F + "bits=8\n") * 2 + LUT, "classification.fields[1].name", "a new name"),
    (LUT.replace("points", "field = 'tag'\npoints"), "classification.luts[0].field", "value"),
    (
        F + "bits=8\n[[classification.luts]]\nfield='d'\npreset='ct'",
        "classification.luts[0].points",
        "points, or table with table_range",
    ),
    (LUT.replace("points", "order = 'pre'\npoints"), "classification.luts[0].order", "[transfer]"),
    (
        "[[classification.luts]]\npoints = [[0, 0, 0, 0, 3]]",
        "classification.luts[0].points[0][4]",
        "0 .. 1",
    ),
    (
        "[transfer]\npreset = 'ct'\n" + LUT,
        "transfer.preset",
        "transfer.gradient_opacity, gradient_illumination and",
    ),
    (G, "geometry.spheres", "[[geometry.spheres]]"),
    (G + "depth_test = '<>'\n" + BALL + "radius=1", "geometry.depth_test", "<, <=, ==, >=, >, !="),
    (G + BALL + "radius=0", "geometry.spheres[0].radius", "> 0"),
    (G + BALL + "radius=1\ncolor=[2,0,0]", "geometry.spheres[0].color[0]", "0 .. 1"),
    (G + "[[geometry.boxes]]\nlo=[0,0,0]\nhi=[1,0,1]", "geometry.boxes[0].hi[1]", "> 0"),
    (G + "color = 'c.npy'", "geometry.depth", "two .npy files"),
    (G + "color = 'c.npy'\ndepth = 'd.npy'\n" + BALL + "radius=1", "geometry.color", "not both"),
]


@pytest.mark.parametrize(("text", "key", "allowed"), BAD)
def test_bad_feature_specs_name_the_key_and_the_allowed_range(text, key, allowed):
    message = error_of(text)
    assert f": {key}:" in message, message
    assert allowed in message, message


def test_arch_feature_keys_default_off_and_are_range_checked():
    base = {"pipeline": {"order": "shear-image", "count": 8, "clock_hz": 125e6}}
    cfg = parse_arch(base, source="m.toml", name="m")
    assert cfg.classification_luts == 1 and cfg.embedded_geometry is False
    vp = resolve_arch("volumepro1000")
    assert vp.classification_luts == 4 and vp.embedded_geometry is True
    assert resolve_arch("volumepro500").classification_luts == 1
    with pytest.raises(InputError, match=r"m.toml: features.classification_luts: .*1 .. 4"):
        parse_arch({**base, "features": {"classification_luts": 5}}, source="m.toml", name="m")
    with pytest.raises(InputError, match=r"m.toml: features.embedded_geometry"):
        parse_arch({**base, "features": {"embedded_geometry": 1}}, source="m.toml", name="m")


def test_user_colour_and_depth_pair_is_loaded_and_checked(tmp_path):
    import numpy as np

    from hwsim.golden.camera import Camera
    from hwsim.golden.geometry import rasterise
    from hwsim.volumes import make_phantom

    colour = np.zeros((8, 8, 3))
    colour[2:4, 2:4] = (1.0, 0.5, 0.0)
    depth = np.ones((8, 8))
    depth[2:4, 2:4] = 0.25
    np.save(tmp_path / "c.npy", colour)
    np.save(tmp_path / "d.npy", depth)
    scene = parse("[view]\nwidth = 8\nheight = 8\n[geometry]\ncolor = 'c.npy'\ndepth = 'd.npy'")
    cam = Camera.from_view(scene.view, make_phantom("ball", size=8))
    buf = rasterise(scene.geometry, cam, 3.0, tmp_path)
    assert buf.depth.tolist() == depth.ravel().tolist()
    assert buf.rgba[2 * 8 + 2].tolist() == [1.0, 0.5, 0.0, 1.0] and buf.rgba[0, 3] == 0.0
    np.save(tmp_path / "d.npy", np.ones((4, 8)))
    with pytest.raises(InputError, match=r"d.npy: geometry.depth: shape \(4, 8\)"):
        rasterise(scene.geometry, cam, 3.0, tmp_path)


def test_cli_refuses_two_luts_on_a_one_lut_machine_with_exit_2(tmp_path, capsys):
    scene = tmp_path / "two.toml"
    scene.write_text(LUT * 2 + "[classification.combine]\nleaf0 = 'add'\n")
    args = [str(scene), "--phantom", "ball:size=8", "--image", "8", "--fidelity", "functional"]
    out = ["--arch", "volumepro500", "--out", str(tmp_path / "o"), "--quiet"]
    for fidelity in ("functional", "golden"):  # golden at the machine's positions too
        args[-1] = fidelity
        code = main(["render", *args, *out])
        assert code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "features.classification_luts" in err[0] and "1 .. 1" in err[0]


def test_the_documented_feature_examples_parse():
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "scenes.md").read_text()
    (classification,) = re.findall(r"```toml classification\n(.*?)```", text, flags=re.S)
    (geometry,) = re.findall(r"```toml geometry\n(.*?)```", text, flags=re.S)
    (cursor,) = re.findall(r"```toml cursor\n(.*?)```", text, flags=re.S)
    scene = parse(classification + geometry + cursor)
    c = scene.classification
    assert [f.name for f in c.fields] == ["density", "tag"]
    assert [lut.field for lut in c.luts] == ["density", "value", "tag"]
    assert c.final.ops == ("mul_b_alpha", "mul_b_alpha")
    assert scene.geometry.depth_test == "<" and len(scene.geometry.boxes) == 1
    assert scene.cursor.width == 3 and scene.cursor.y.opacity == 0.6


FEATURE_VALUES = st.one_of(
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(["a", "add", "mul_b_alpha", "value", "<", "x"]),
    st.booleans(),
    st.lists(st.integers(-5, 5), max_size=4),
    st.dictionaries(st.sampled_from(["rgb", "alpha", "x"]), st.sampled_from(["a", "or"])),
)
FEATURE_KEYS = {
    "fields": ["name", "lsb", "bits"],
    "luts": ["field", "entries", "points", "preset", "order"],
    "combine": ["leaf0", "leaf1", "final"],
    "spheres": ["center", "radius", "color"],
    "boxes": ["lo", "hi", "color"],
    "geometry": ["depth_test", "color", "depth"],
}


@settings(max_examples=300, deadline=None)
@given(part=st.sampled_from(sorted(FEATURE_KEYS)), data=st.data(), value=FEATURE_VALUES)
def test_any_feature_value_is_accepted_or_refused_with_one_line_input_error(part, data, value):
    key = data.draw(st.sampled_from(FEATURE_KEYS[part]))
    lut = {"points": [[0, 0, 0, 0, 0], [1, 1, 1, 1, 1]]}
    ball = {"center": [0, 0, 0], "radius": 1}
    doc = {
        "fields": {
            "classification": {"fields": [{"name": "d", "bits": 8, key: value}], "luts": [lut]}
        },
        "luts": {"classification": {"luts": [{**lut, key: value}]}},
        "combine": {"classification": {"luts": [lut, lut], "combine": {"leaf0": "a", key: value}}},
        "spheres": {"geometry": {"spheres": [{**ball, key: value}]}},
        "boxes": {"geometry": {"boxes": [{"lo": [0, 0, 0], "hi": [1, 1, 1], key: value}]}},
        "geometry": {"geometry": {"spheres": [ball], key: value}},
    }[part]
    try:
        parse_scene(doc, source="t.toml")
    except InputError as exc:
        message = str(exc)
        assert message.startswith("t.toml: ") and "\n" not in message
        assert "classification" in message or "geometry" in message or "transfer" in message
