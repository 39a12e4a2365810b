"""Back-to-front blending (VLI's kVLIBlendBTF) on the machines that had it (issue 16).

A back-to-front plan walks the same samples as the front-to-back plan, each ray from its
far end; every rung follows the plan and the compositor blends ``C = a c + (1 - a) C``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs

from hwsim.core.errors import InputError
from hwsim.golden import make_plan, render_golden
from hwsim.golden.render import occupancy_for
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import parse_scene
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of

pytestmark = pytest.mark.model

BTF = {"blend_order": "back-to-front"}


@pytest.fixture(scope="module")
def head():
    # At 24^3 the two blend orders differ in a handful of pixels, and with seed 0's noise
    # in none (the fixed-point sums happen to round alike): seed 1 keeps a difference.
    return make_phantom("head", size=24, seed=1)


def _samples(plan):
    """Every planned sample as ``{(ray, position rounded to 1e-9)}`` and its step."""
    out = {}
    for j, step in enumerate(plan.steps()):
        for ray, p in zip(step.rays.tolist(), np.round(step.zyx, 9).tolist(), strict=True):
            out[(ray, tuple(p))] = j
    return out


@pytest.mark.parametrize(
    ("sampling", "projection", "ss"),
    [
        ("ray", "parallel", 1.0),
        ("ray", "perspective", 1.0),
        ("shear-warp", "parallel", 1.0),
        ("shear-warp", "parallel", 3.0),
        ("shear-image", "parallel", 2.0),
        ("shear-image", "perspective", 1.0),
    ],
)
@pytest.mark.parametrize("leap", [False, True], ids=["all", "leapt"])
def test_a_back_to_front_plan_walks_the_same_samples_far_first(
    head, sampling, projection, ss, leap
):
    ftb = rungs.scene_of(35, 25, size=20, projection=projection, render={"supersampling": ss})
    btf = ftb.replace(render=dataclasses.replace(ftb.render, **BTF))
    tf = resolve_transfer(ftb.transfer, head)
    occupancy = occupancy_for(ftb, head, tf) if leap else None
    front = make_plan(ftb, head, sampling, occupancy=occupancy)
    back = make_plan(btf, head, sampling, occupancy=occupancy)
    assert back.back_to_front and not front.back_to_front
    first, second = _samples(front), _samples(back)
    assert first.keys() == second.keys() and len(first) == front.samples == back.samples
    last = front.n_steps - 1
    assert all(second[k] == last - j for k, j in first.items())


def test_golden_blends_back_to_front_to_the_front_to_back_image(head):
    ftb = rungs.scene_of(35, 25, size=24)
    btf = ftb.replace(render=dataclasses.replace(ftb.render, **BTF))
    tf = resolve_transfer(ftb.transfer, head)
    for sampling in ("ray", "shear-warp"):
        a = render_golden(ftb, head, tf, sampling=sampling).image
        b = render_golden(btf, head, tf, sampling=sampling).image
        # The same integral, summed in the other order: equal to float64 rounding.
        assert np.abs(a - b).max() < 1e-12 and a.max() > 0.1


def _psnr(a, b):
    return 10 * np.log10(1.0 / np.mean((a - b) ** 2))


@pytest.mark.parametrize("name", ["volumepro500", "volumepro1000"])
def test_back_to_front_on_the_machines_that_had_it(head, name):
    """As built (no --extend): the cycle image is the functional image bit for bit, the
    transaction rung's cycles within its contract, and the fixed-point blend is its own
    arithmetic (not the front-to-back image) yet as close to golden."""
    ftb = rungs.scene_of(35, 25, size=24)
    btf = ftb.replace(render=dataclasses.replace(ftb.render, **BTF))
    fixed, cycle, plan = rungs.functional_and_cycle(btf, head, name)
    assert plan.back_to_front
    rungs.assert_identical(fixed, cycle)
    exact, approx = rungs.within_contract(btf, head, name)
    front = render(ftb, fidelity="functional", arch=resolve_arch(name), volume=head).image
    gold = render(btf, fidelity="golden", arch=resolve_arch(name), volume=head).image
    assert not np.array_equal(front, fixed.image)
    assert _psnr(fixed.image, gold) > 50.0
    assert abs(_psnr(fixed.image, gold) - _psnr(front, gold)) < 1.0


@pytest.mark.parametrize(
    ("render_table", "key"),
    [
        ('mode = "mip"\nblend_order = "back-to-front"', "render.blend_order"),
        ('blend_order = "back-to-front"\nearly_termination = 0.9', "render.early_termination"),
        ('blend_order = "sideways"', "render.blend_order"),
    ],
)
def test_a_blend_order_the_scene_cannot_use_is_refused(render_table, key):
    import tomllib

    data = tomllib.loads("[render]\n" + render_table)
    with pytest.raises(InputError) as info:
        parse_scene(data, source="s.toml")
    assert info.value.key == key


def test_the_rtl_top_refuses_back_to_front_even_as_a_what_if(head):
    from rtl.frame import prepare

    scene = rungs.scene_of(35, 25, size=12, render=BTF)
    volume = make_phantom("head", size=12)
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), resolve_arch("cube4"))
    with pytest.raises(InputError) as info:
        prepare(frame)
    assert info.value.key == "render.blend_order"


@pytest.mark.parametrize("name", ["volumepro500", "volumepro1000"])
def test_the_compiled_kernel_blends_back_to_front_as_the_unit_chain(name):
    from models import fused
    from models.backend import Backend
    from models.functional import render_functional

    volume = make_phantom("head", size=48)
    scene = rungs.scene_of(35, 25, size=64, render=BTF)
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), resolve_arch(name))
    assert fused.eligible(Backend(frame))  # the kernel runs this frame
    kernel = render_functional(frame)
    chain = render_functional(frame, compiled=False)
    assert np.array_equal(kernel.image, chain.image) and kernel.image.max() > 0.1
    assert (kernel.samples, kernel.cycles) == (chain.samples, chain.cycles)
