"""The compiled leap of ideal-ray plans gives the NumPy march's step ranges exactly."""

from __future__ import annotations

import numpy as np
import pytest
from golden_helpers import gaussian_volume, make_scene

from hwsim.golden import make_plan
from hwsim.golden.leap_rays import leap_ray_plan
from hwsim.golden.occupancy import occupancy_from_ranges
from hwsim.volumes import make_phantom

pytestmark = pytest.mark.golden


def _occupancy(shape, fraction, seed):
    rng = np.random.default_rng(seed)
    blocks = tuple(-(-n // 4) for n in shape)
    return occupancy_from_ranges(rng.random(blocks) < fraction)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"projection": "perspective", "zoom": 1.4},
        {"blend_order": "back-to-front"},
        {"sample_spacing": 0.37},
    ],
    ids=["parallel", "perspective", "back-to-front", "fine-steps"],
)
def test_compiled_leap_equals_the_numpy_march(seed, kw):
    rng = np.random.default_rng(100 + seed)
    shape = tuple(int(v) for v in rng.integers(5, 40, 3))
    spacing = tuple(float(v) for v in rng.uniform(0.5, 2.0, 3))
    volume = gaussian_volume(shape, spacing=spacing)
    az, el = (float(v) for v in rng.uniform(-180, 180, 2))
    scene = make_scene(az=az, el=el / 2, size=37, height=29, **kw)
    plan = make_plan(scene, volume, "ray")
    occupancy = _occupancy(shape, [0.05, 0.3, 0.8][seed % 3], seed)
    lo, hi = leap_ray_plan(plan, occupancy)
    ref_lo, ref_hi = plan._march(occupancy)
    assert np.array_equal(lo, ref_lo) and np.array_equal(hi, ref_hi)
    assert (hi - lo).sum() < (plan.j_hi - plan.j_lo).sum()  # something was leapt
    empty = lo > hi  # the canonical empty ray: j_lo = j_hi + 1, j_hi as planned
    assert np.array_equal(lo[empty], plan.j_hi[empty] + 1)
    assert np.array_equal(hi[empty], plan.j_hi[empty])


def test_a_real_plan_is_leapt_the_same_on_the_phantom():
    volume = make_phantom("head", size=48)
    scene = make_scene(az=30, el=15, size=64)
    plan = make_plan(scene, volume, "ray")
    from hwsim.golden.occupancy import block_ranges, opacity_can_be_positive

    lo, hi = block_ranges(volume.data)
    occ = occupancy_from_ranges(
        opacity_can_be_positive(lo, hi, np.array([0.0, 500.0, 2000.0]), np.array([0.0, 0.0, 1.0]))
    )
    assert np.array_equal(np.stack(leap_ray_plan(plan, occ)), np.stack(plan._march(occ)))


@pytest.mark.parametrize("perspective", [False, True])
def test_the_narrow_distance_field_leaps_the_same(monkeypatch, perspective):
    """int8 distances (and the per-distance leap table of a shared step) against the
    int64 field, and a field too far for int16 kept as int64."""
    from hwsim.golden import leap_rays

    volume = gaussian_volume((30, 26, 34))
    kw = {"projection": "perspective", "zoom": 1.3} if perspective else {}
    plan = make_plan(make_scene(az=40, el=20, size=33, **kw), volume, "ray")
    occupancy = _occupancy(volume.shape, 0.05, 3)
    assert leap_rays._compact(occupancy.distance)[0].dtype == np.int8
    narrow = leap_ray_plan(plan, occupancy)
    monkeypatch.setattr(leap_rays, "_compact", lambda d: (d, int(d.max())))
    assert np.array_equal(np.stack(narrow), np.stack(leap_ray_plan(plan, occupancy)))
    far = np.full((3, 3, 3), 40000, dtype=np.int64)
    found = leap_rays._COMPACT.get(id(far))  # an id may be a dead array's: not ``far``
    assert found is None or found[0]() is not far
    monkeypatch.undo()
    assert leap_rays._compact(far)[0].dtype == np.int64
