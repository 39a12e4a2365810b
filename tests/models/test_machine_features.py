"""Each machine renders as it did: one declared feature set, honoured or refused alike at
every rung (issue 16).

The walk renders every scene key that asks something of a machine (modes, classification
order, interpolation, gradient source, crop, cut planes, early termination, projection,
supersampling, volume size, sections) on every built-in machine at every rung, and
asserts that the rungs agree: all render it or all refuse it, naming the same key.  The
rtl rung is checked up to the point where the simulator would start (``prepare``): it may
refuse more (the RTL top's documented limits), never less.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.run.fidelity import builtin_archs, check_family, check_scene_fits, render, resolve_arch
from hwsim.spec.scene import CropSpec, CutPlane, Scene, VolumeSpec, load_scene
from hwsim.spec.scene_cursor import CursorSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom

pytestmark = pytest.mark.model

RUNGS = ("golden", "functional", "transaction", "cycle")
#: Gradient-magnitude illumination modulation: dim the light of flat regions.
GMIM = ((0.0, 0.2), (200.0, 1.0))
SIZE = 12


def _base() -> Scene:
    scene = load_scene("head").replace(volume=VolumeSpec(phantom="head", params=(("size", SIZE),)))
    return scene.replace(view=dataclasses.replace(scene.view, width=SIZE, height=SIZE))


def _render_changes(**changes):
    return lambda s: s.replace(render=dataclasses.replace(s.render, **changes))


#: One scene per feature a machine may lack, from the head scene.
VARIANTS = {
    **{f"mode-{m}": _render_changes(mode=m) for m in ("mip", "minip", "xray", "iso")},
    "pre-classified": lambda s: s.replace(transfer=dataclasses.replace(s.transfer, order="pre")),
    "nearest": _render_changes(interpolation="nearest"),
    "gradient-sample": _render_changes(gradient="sample"),
    "gradient-voxel": _render_changes(gradient="voxel"),
    "crop": lambda s: s.replace(crop=CropSpec(x=(2.0, 9.0))),
    "one-cut-plane": lambda s: s.replace(cut_planes=(CutPlane(thickness=3.0),)),
    "two-cut-planes": lambda s: s.replace(cut_planes=(CutPlane(), CutPlane(normal=(1.0, 0, 0)))),
    "ert": _render_changes(early_termination=0.9),
    "back-to-front": _render_changes(blend_order="back-to-front"),
    "cursor": lambda s: s.replace(cursor=CursorSpec(position=(6.0, 6.0, 6.0), width=3)),
    "perspective": lambda s: s.replace(view=dataclasses.replace(s.view, projection="perspective")),
    "supersampling-2": _render_changes(supersampling=2.0),
    "gradient-illumination": lambda s: s.replace(
        transfer=dataclasses.replace(s.transfer, gradient_illumination=GMIM)
    ),
}


def _outcome(scene, volume, arch, rung, extend=False):
    try:
        render(scene, fidelity=rung, arch=arch, volume=volume, extend=extend)
    except InputError as exc:
        return exc.key
    return "ok"


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=SIZE)


@pytest.mark.parametrize("extend", [False, True], ids=["as-built", "what-if"])
@pytest.mark.parametrize("variant", list(VARIANTS))
@pytest.mark.parametrize("name", list(builtin_archs()))
def test_every_rung_honours_or_refuses_the_scene_alike(head, name, variant, extend):
    arch = resolve_arch(name)
    scene = VARIANTS[variant](_base())
    outcomes = {rung: _outcome(scene, head, arch, rung, extend) for rung in RUNGS}
    assert len(set(outcomes.values())) == 1, outcomes
    if name.startswith("cube4") and outcomes["cycle"] != "ok" and not extend:
        _assert_rtl_refuses(scene, head, arch)


def _assert_rtl_refuses(scene, volume, arch):
    """What the cycle rung refuses, the rtl rung refuses before it simulates anything."""
    from models.frame import frame_of
    from rtl.frame import prepare

    with pytest.raises(InputError):
        check_scene_fits(scene, arch)
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
        check_family(frame)
        prepare(frame)


@pytest.mark.parametrize(
    ("name", "variant", "key"),
    [
        ("cube4", "mode-xray", "render.mode"),
        ("cube4", "pre-classified", "transfer.order"),
        ("cube4", "crop", "crop"),
        ("cube4", "one-cut-plane", "cut_planes"),
        ("cube4", "ert", "render.early_termination"),
        ("cube4", "back-to-front", "render.blend_order"),
        ("volumepro1000", "cursor", "cursor"),
        ("em-cube", "mode-minip", "render.mode"),
        ("vizard2", "mode-iso", "render.mode"),
        ("vizard2", "crop", "crop"),
        ("volumepro500", "pre-classified", "transfer.order"),
        ("volumepro500", "two-cut-planes", "cut_planes"),
        ("volumepro500", "gradient-voxel", "render.gradient"),
        ("volumepro1000", "nearest", "render.interpolation"),
        ("volumepro1000", "gradient-illumination", "transfer.gradient_illumination"),
    ],
)
def test_what_a_machine_never_had_is_refused_naming_the_feature(head, name, variant, key):
    scene = VARIANTS[variant](_base())
    with pytest.raises(InputError) as exc:
        render(scene, fidelity="functional", arch=name, volume=head)
    assert exc.value.key == key and name in exc.value.message


def test_the_published_feature_sets_render(head):
    """What each machine had renders without --extend (a refusal here would be a wrong
    declaration, not a safe one)."""
    had = {
        "volumepro500": [
            "mode-mip",
            "mode-minip",
            "crop",
            "one-cut-plane",
            "supersampling-2",
            "gradient-illumination",
        ],
        "volumepro1000": ["mode-xray", "mode-iso", "pre-classified", "two-cut-planes", "ert"],
        "vizard2": ["mode-mip", "ert", "perspective", "supersampling-2"],
        "cube4": ["mode-mip", "perspective", "gradient-sample"],
    }
    for name, variants in had.items():
        for variant in variants:
            scene = VARIANTS[variant](_base())
            run = render(scene, fidelity="functional", arch=name, volume=head)
            assert run.extensions == [], (name, variant)


def test_extend_renders_a_what_if_at_every_rung_and_lists_it(head):
    scene = VARIANTS["mode-xray"](_base())
    runs = [render(scene, fidelity=r, arch="cube4", volume=head, extend=True) for r in RUNGS]
    for run in runs:
        assert [e["feature"] for e in run.extensions] == ["modes"]
        assert run.extensions[0]["asked"] == "xray"
        assert run.extensions[0]["source"].startswith("[V]")
    assert (runs[1].image == runs[3].image).all()  # still bit-identical rungs


def test_an_arch_file_may_opt_in_to_what_ifs(tmp_path, head):
    from hwsim.spec.arch import load_arch_file

    text = Path(resolve_arch("cube4").source).read_text()
    path = tmp_path / "cube4-whatif.toml"
    path.write_text(text.replace("[features]\n", "[features]\nextend = true\n", 1))
    arch = load_arch_file(path)
    run = render(VARIANTS["crop"](_base()), fidelity="functional", arch=arch, volume=head)
    assert [e["feature"] for e in run.extensions] == ["crop"]


def test_every_builtin_feature_cites_a_tagged_source():
    for name, arch in builtin_archs().items():
        for feature in ("modes", "classification", "interpolation", "gradients", "crop"):
            source = arch.feature_sources.get(feature, "")
            assert source[:3] in ("[V]", "[R ", "[I]", "[?]") or source[:4] == "[R]", (
                name,
                feature,
            )


def test_sections_are_refused_where_the_model_has_none(head):
    scene = _base()
    for name in ("cube4", "vizard2"):
        arch = dataclasses.replace(resolve_arch(name), section_width=4)
        for rung in RUNGS:
            with pytest.raises(InputError, match="overheads.section_width"):
                render(scene, fidelity=rung, arch=arch, volume=head)


def test_cli_refuses_with_one_line_and_extend_writes_the_extensions(tmp_path, capsys):
    args = ["render", "--phantom", "ball:size=8", "--image", "8", "--mode", "xray"]
    args += ["--fidelity", "functional", "--arch", "cube4", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "render.mode" in err and "--extend" in err
    assert main([*args, "--extend", "--out", str(tmp_path / "b")]) == 0
    stats = json.loads((tmp_path / "b" / "stats.json").read_text())
    assert [e["feature"] for e in stats["extensions"]] == ["modes"]


def test_the_docs_feature_table_is_the_arch_files():
    from hwsim.spec.machine_features import features_markdown

    docs = (Path(__file__).parents[2] / "docs" / "architectures.md").read_text()
    table = docs.split("<!-- features:begin -->\n")[1].split("<!-- features:end -->")[0]
    assert table == features_markdown(builtin_archs())


def test_gradient_illumination_modulation_on_volumepro_500(head):
    """VolumePro 500's GMIM: the same table index as opacity modulation scales diffuse and
    specular light; golden applies the same factor in float64, every rung the same bits,
    and the image differs from the unmodulated one."""
    from hwsim.numerics import psnr

    scene = VARIANTS["gradient-illumination"](_base())
    runs = {r: render(scene, fidelity=r, arch="volumepro500", volume=head) for r in RUNGS}
    plain = render(_base(), fidelity="functional", arch="volumepro500", volume=head)
    assert not np.array_equal(runs["functional"].image, plain.image)
    for rung in ("transaction", "cycle"):
        assert np.array_equal(runs[rung].image, runs["functional"].image)
    modulated = psnr(runs["golden"].image, runs["functional"].image)
    unmodulated_golden = render(_base(), fidelity="golden", arch="volumepro500", volume=head)
    assert modulated > 40.0
    assert modulated > psnr(unmodulated_golden.image, runs["functional"].image)
