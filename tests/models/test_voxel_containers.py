"""32-bit voxels on VolumePro 1000 (issue 16): containers of up to four fields of 4..16
bits, the value path reading one of them (VLI's gradient source), two SDRAM words each.

# Ref: architectures.md section 4 ([V] vli.h: 8, 16 or 32 bits per voxel, up to 4
#      fields of 4..16 bits); the two-word layout is [I].
"""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
import rungs

from hwsim.core.errors import InputError
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import parse_scene
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume

pytestmark = pytest.mark.model

N = 24
SCENE = """
[view]
azimuth = 30
elevation = 20
width = 24
height = 24
[transfer]
order = "{order}"
[classification]
{value_field}
[[classification.fields]]
name = "density"
lsb = 0
bits = 12
[[classification.fields]]
name = "tag"
lsb = {tag_lsb}
bits = 4
[[classification.luts]]
field = "density"
entries = 4096
points = [[0, 0, 0, 0, 0], [1500, 0.8, 0.6, 0.5, 0.0], [2500, 0.9, 0.8, 0.7, 0.3],
          [4095, 1, 1, 1, 0.8]]
[[classification.luts]]
field = "tag"
entries = 256
points = [[0, 0, 0, 0, 0], [15, 0.2, 0.4, 1.0, 0.5]]
[classification.combine]
leaf0 = {{ rgb = "max", alpha = "add" }}
"""


def _scene(tag_lsb: int, *, value_field: str | None = "density", order: str = "post"):
    field = f'value_field = "{value_field}"' if value_field else ""
    text = SCENE.format(tag_lsb=tag_lsb, value_field=field, order=order)
    return parse_scene(tomllib.loads(text), source="containers.toml")


@pytest.fixture(scope="module")
def containers():
    """The same density (12 bits) and tag (4 bits) in a 32-bit container (tag at bit 16,
    noise in bits 24..31 that no field reads) and in a 16-bit one (tag at bit 12)."""
    head = make_phantom("head", size=N).data.astype(np.int64)
    density = (head - head.min()) * 4095 // (head.max() - head.min())
    z, y, x = np.mgrid[:N, :N, :N]
    tag = 12 * (((x - N / 2) ** 2 + (y - N / 2) ** 2 + (z - N / 2) ** 2) < (N / 4) ** 2)
    noise = np.random.default_rng(7).integers(0, 256, density.shape)
    wide = Volume(data=(density | (tag << 16) | (noise << 24)).astype(np.uint32), name="c32")
    narrow = Volume(data=(density | (tag << 12)).astype(np.uint16), name="c16", bits=16)
    return wide, narrow


def test_a_32_bit_container_renders_as_the_same_fields_in_16_bits(containers):
    """Every rung: the image of the fields is the image of the same fields in a 16-bit
    container (bits 24..31 are read by nothing); cycle and functional agree bit for bit;
    the 32-bit frame reads two bursts per mini-block, and takes longer."""
    wide, narrow = containers
    arch = resolve_arch("volumepro1000")
    runs = {}
    for name, scene, volume in (("32", _scene(16), wide), ("16", _scene(12), narrow)):
        for rung in ("golden", "functional", "transaction", "cycle"):
            runs[name, rung] = render(scene, fidelity=rung, arch=arch, volume=volume)
    for rung in ("golden", "functional", "cycle"):
        assert np.array_equal(runs["32", rung].image, runs["16", rung].image), rung
    assert runs["32", "functional"].image.max() > 0.5
    assert np.array_equal(runs["32", "cycle"].image, runs["32", "functional"].image)
    cycle, narrow_cycle = runs["32", "cycle"], runs["16", "cycle"]
    rungs.assert_within_contract(cycle.cycles, runs["32", "transaction"].cycles)
    bursts = cycle.counters["memory.sdram.bursts"]
    assert bursts == 2 * narrow_cycle.counters["memory.sdram.bursts"]
    assert cycle.cycles > 1.5 * narrow_cycle.cycles  # memory-bound at two words a voxel
    assert runs["32", "transaction"].counters["memory.read_bytes"] == bursts * 16


def test_a_32_bit_supervolume_slices_its_containers_with_its_bricks(containers):
    wide, _ = containers
    arch = dataclasses.replace(resolve_arch("volumepro1000"), max_volume=(16, 16, 16))
    scene = _scene(16)
    fixed = render(scene, fidelity="functional", arch=arch, volume=wide, extend=True)
    cycle = render(scene, fidelity="cycle", arch=arch, volume=wide, extend=True)
    assert np.array_equal(fixed.image, cycle.image)
    one = render(scene, fidelity="functional", arch=resolve_arch("volumepro1000"), volume=wide)
    assert np.abs(fixed.image - one.image).max() < 4 / 4095 + 2 / 255


@pytest.mark.parametrize(
    ("name", "changes", "key"),
    [
        ("volumepro500", {}, "limits.voxel_bits"),
        ("volumepro1000", {"value_field": None}, "classification.value_field"),
        ("volumepro1000", {"order": "pre"}, "transfer.order"),
    ],
)
def test_what_a_container_cannot_do_is_refused(containers, name, changes, key):
    wide, _ = containers
    scene = _scene(16, **changes)
    if name == "volumepro500":  # one LUT, as that machine had: only the width is refused
        one = dataclasses.replace(scene.classification, luts=scene.classification.luts[:1])
        scene = scene.replace(classification=one)
    with pytest.raises(InputError) as info:
        render(scene, fidelity="cycle", arch=resolve_arch(name), volume=wide)
    assert info.value.key == key


def test_a_value_field_needs_unsigned_integer_voxels():
    floats = make_phantom("head", size=12)  # int16 CT-like data
    scene = rungs.scene_of(size=12).replace(classification=_scene(16).classification)
    with pytest.raises(InputError) as info:
        render(scene, fidelity="functional", arch=resolve_arch("volumepro1000"), volume=floats)
    assert info.value.key == "classification.value_field"
