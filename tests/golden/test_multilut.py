"""Multi-LUT classification with combiners: golden vs functional on volumepro1000 (head
phantom, a field-split 16-bit volume, the real CT), wiring checks and refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.core.errors import InputError
from hwsim.golden import render_golden
from hwsim.numerics import psnr
from hwsim.run.fidelity import render
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec, load_scene
from hwsim.spec.scene_features import AluSpec, ClassificationSpec, LutSpec, VoxelField
from hwsim.spec.transfer import preset_points, resolve_transfer
from hwsim.volumes import make_phantom, read_volume
from hwsim.volumes.volume import Volume

pytestmark = [pytest.mark.golden, pytest.mark.model]

ARCH = "volumepro1000"
SKIN = ((-1024, 0, 0, 0, 0), (-400, 0.75, 0.45, 0.35, 0), (-150, 0.85, 0.55, 0.45, 0.02),
        (150, 0.9, 0.62, 0.52, 0.02), (250, 0.95, 0.88, 0.78, 0))  # fmt: skip
BONE = ((-1024, 0, 0, 0, 0), (250, 0.95, 0.88, 0.78, 0), (450, 0.96, 0.92, 0.84, 0.45),
        (1200, 1, 0.98, 0.92, 0.85), (3072, 1, 1, 1, 0.9))  # fmt: skip


def lut(points, entries=4096, field="value") -> LutSpec:
    return LutSpec(field=field, entries=entries, transfer=TransferSpec(preset=None, points=points))


def head_scene(classification, size=48, image=48, **render_kw) -> Scene:
    return Scene(
        volume=VolumeSpec(phantom="head", params=(("size", size),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=image, height=image, zoom=1.3),
        render=RenderSpec(**render_kw),
        classification=classification,
    )


def both(sc: Scene, volume):
    tf = resolve_transfer(sc.transfer, volume)
    g = render_golden(sc, volume, tf, sampling="shear-image", leap=False)
    f = render(sc, fidelity="functional", arch=ARCH, volume=volume)
    return g, f


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=48)


def test_one_lut_section_renders_exactly_like_the_transfer_function(head):
    ct = tuple(tuple(r) for r in preset_points("ct", head))
    plain = head_scene(None)
    one = head_scene(ClassificationSpec(luts=(lut(ct),)))
    g0, f0 = both(plain, head)
    g1, f1 = both(one, head)
    assert np.array_equal(g1.image, g0.image)
    assert np.array_equal(f1.image, f0.image)  # same LUT, same bits


@pytest.mark.parametrize("order", ["post", "pre"])
def test_two_luts_on_one_field_meet_40_db_and_combine_both_tables(head, order):
    # Both 4096-entry LUTs on leaf0 (allowed: one leaf holds the big tables).  A 256-entry
    # table over 16-bit voxels steps 256 HU per entry: far from the float function.
    spec = ClassificationSpec(luts=(lut(SKIN), lut(BONE)), leaf0=AluSpec(rgb="max", alpha="add"))
    sc = head_scene(spec)
    sc = sc.replace(transfer=TransferSpec(preset=None, points=SKIN, order=order))
    g, f = both(sc, head)
    assert psnr(g.image, f.image) >= 40.0
    skin_only = head_scene(ClassificationSpec(luts=(lut(SKIN),)))
    gs = render_golden(
        skin_only, head, resolve_transfer(skin_only.transfer, head), sampling="shear-image"
    )
    assert g.image[..., 3].sum() > gs.image[..., 3].sum() + 10.0  # the bone LUT adds opacity


def tagged_head(size=48) -> Volume:
    """16-bit voxels: 12-bit density (HU + 1024) in bits 4..15, a 4-bit tag in bits 0..3
    (tag 1 on the left half of the volume, 2 on the right)."""
    hu = make_phantom("head", size=size).data.astype(np.int64)
    density = np.clip(hu + 1024, 0, 4095)
    tag = np.where(np.arange(size)[None, None, :] < size // 2, 1, 2)
    data = ((density << 4) | tag).astype(np.uint16)
    return Volume(data=data, name="tagged-head", bits=16)


def tagged_scene(order="post") -> Scene:
    shifted = lambda pts: tuple((v + 1024, *rest) for v, *rest in pts)  # noqa: E731
    mask = ((0, 0, 0, 0, 0), (1, 1, 1, 1, 1), (1.5, 0, 0, 0, 0), (15, 0, 0, 0, 0))
    spec = ClassificationSpec(
        fields=(VoxelField(name="density", lsb=4, bits=12), VoxelField(name="tag", lsb=0, bits=4)),
        luts=(
            lut(shifted(SKIN), field="density"),
            lut(shifted(BONE), field="density"),
            lut(mask, entries=256, field="tag"),
        ),
        leaf0=AluSpec(rgb="max", alpha="add"),
        final=AluSpec(rgb="mul_b_alpha", alpha="mul_b_alpha"),
    )
    return Scene(
        volume=VolumeSpec(phantom="head"),
        transfer=TransferSpec(preset="auto", order=order),
        view=ViewSpec(azimuth=0, elevation=0, width=48, height=48, zoom=1.3),
        render=RenderSpec(lighting=False),
        classification=spec,
    )


@pytest.mark.parametrize("order", ["post", "pre"])
def test_tag_field_masks_half_the_head_and_meets_40_db(order):
    volume = tagged_head()
    g, f = both(tagged_scene(order), volume)
    assert psnr(g.image, f.image) >= 40.0
    # View along +z: right = d x up = -x, so image column c sees volume x ~ 47 - c; the
    # tag-2 half (x >= 24) is masked out on the image's left.
    for img in (g.image, f.image):
        assert img[:, :18, 3].max() == 0.0
        assert img[:, 30:, 3].max() > 0.5


def test_all_four_luts_and_three_alus_meet_40_db():
    shifted = lambda pts: tuple((v + 1024, *rest) for v, *rest in pts)  # noqa: E731
    tint = ((0, 0.2, 0.9, 0.3, 0.0), (15, 0.2, 0.9, 0.3, 0.0))
    mask = ((0, 0, 0, 0, 0), (1, 1, 1, 1, 1), (1.5, 0, 0, 0, 0), (15, 0, 0, 0, 0))
    base = tagged_scene()
    spec = dataclasses.replace(
        base.classification,
        luts=(
            lut(shifted(SKIN), field="density"),
            lut(shifted(BONE), field="density"),
            lut(tint, entries=256, field="tag"),
            lut(mask, entries=256, field="tag"),
        ),
        leaf0=AluSpec(rgb="max", alpha="add"),
        leaf1=AluSpec(rgb="add", alpha="b"),
        final=AluSpec(rgb="mul2", alpha="mul_b_alpha"),
    )
    g, f = both(base.replace(classification=spec), tagged_head())
    assert psnr(g.image, f.image) >= 40.0
    assert f.image[:, 30:, 3].max() > 0.5 and f.image[:, :18, 3].max() == 0.0


def test_real_ct_with_two_luts_meets_40_db(shared_data):
    ct = read_volume(shared_data / "ct_cranium.nrrd")
    spec = ClassificationSpec(
        luts=(lut(SKIN), lut(BONE, entries=256)), leaf0=AluSpec(rgb="max", alpha="add")
    )
    sc = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=180, elevation=0, width=64, height=64, zoom=1.2),
        classification=spec,
    )
    g, f = both(sc, ct)
    assert f.samples == g.samples
    assert psnr(g.image, f.image) >= 40.0


def test_builtin_vp1000_scene_renders_and_meets_40_db():
    sc = load_scene("head-vp1000")
    assert sc.classification is not None and sc.geometry is not None
    small = sc.replace(
        volume=VolumeSpec(phantom="head", params=(("size", 64),)),
        view=dataclasses.replace(sc.view, width=64, height=64),
    )
    volume = make_phantom("head", size=64)
    g, f = both(small, volume)
    assert psnr(g.image, f.image) >= 40.0


# ----------------------------------------------------------------- refusal


@pytest.mark.parametrize("arch", ["volumepro500", "cube4"])
def test_machines_with_one_lut_refuse_two(head, arch):
    sc = head_scene(ClassificationSpec(luts=(lut(SKIN), lut(BONE)), leaf0=AluSpec(rgb="add")))
    with pytest.raises(InputError, match="features.classification_luts") as err:
        render(sc, fidelity="functional", arch=arch, volume=head)
    assert "allowed: 1 .. 1" in str(err.value)


def test_declared_fields_need_unsigned_stored_voxels(head):
    spec = ClassificationSpec(
        fields=(VoxelField(name="d", lsb=4, bits=12),), luts=(lut(((0, 0, 0, 0, 0),), field="d"),)
    )
    with pytest.raises(InputError, match=r"classification.fields\[0\]"):
        render(head_scene(spec), fidelity="functional", arch=ARCH, volume=head)


@pytest.mark.parametrize("order", ["post", "pre"])
def test_cycle_rung_shares_the_features_bit_for_bit(order):
    """The hooks live in the shared back end: a Cube-4 variant given both features (the
    cycle rung models slice-parallel machines) renders the same bits at both rungs."""
    from hwsim.core.config import read_toml
    from hwsim.run.fidelity import resolve_arch
    from hwsim.spec.arch import parse_arch

    data = read_toml(resolve_arch("cube4").source)
    data.setdefault("features", {}).update(
        classification_luts=4, embedded_geometry=True, classification=["post", "pre"]
    )
    arch = parse_arch(data, source="cube4-vp.toml", name="cube4-vp")
    sc = load_scene("head-vp1000")
    sc = sc.replace(
        volume=VolumeSpec(phantom="head", params=(("size", 32),)),
        view=dataclasses.replace(sc.view, width=32, height=32, projection="perspective"),
        transfer=dataclasses.replace(sc.transfer, order=order),
    )
    volume = make_phantom("head", size=32)
    f = render(sc, fidelity="functional", arch=arch, volume=volume)
    c = render(sc, fidelity="cycle", arch=arch, volume=volume)
    assert f.samples == c.samples > 0
    assert np.array_equal(f.image, c.image)


def test_the_combiners_and_depth_test_are_listed_and_timed_when_used():
    from hwsim.run.fidelity import elaboration
    from models.functional import pipeline_latency
    from models.units import combine, depth

    sc = load_scene("head-vp1000")
    tf = resolve_transfer(sc.transfer, make_phantom("head", size=8))
    used, elided = elaboration(sc, tf)
    assert used.index("classify") < used.index("combine") < used.index("shade")
    assert "depth" in used and "combine" not in elided and "depth" not in elided
    plain = sc.replace(classification=None, geometry=None)
    assert "combine" not in elaboration(plain, tf)[0] + elaboration(plain, tf)[1]
    latency = pipeline_latency(sc, tf.modulates)
    assert latency == pipeline_latency(plain, tf.modulates) + combine.LATENCY + depth.LATENCY
