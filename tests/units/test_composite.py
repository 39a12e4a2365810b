"""Compositor unit model against float64 compositing (hwsim/golden/render.py formulas)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.numerics import SATURATIONS
from models.units import composite as cu

pytestmark = pytest.mark.model

CFG = cu.CompositeConfig()
ONE = 1 << CFG.acc_frac_bits
H = 2.0**-17


def golden_ftb(rgb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Float64 front-to-back (render.py), samples along axis 0, rays along axis 1."""
    acc = np.zeros((alpha.shape[1], 4))
    for c, a in zip(rgb, alpha, strict=True):
        w = (1.0 - acc[:, 3]) * a
        acc[:, :3] += w[:, None] * c
        acc[:, 3] += w
    return acc


def run_ftb(rgb_raw: np.ndarray, alpha_raw: np.ndarray, cfg=CFG) -> np.ndarray:
    n_rays = alpha_raw.shape[1]
    acc = np.zeros((n_rays, 4), dtype=np.int64)
    rays = np.arange(n_rays)
    for c, a in zip(rgb_raw, alpha_raw, strict=True):
        cu.front_to_back(acc, rays, c, a, cfg)
    return acc


@pytest.mark.parametrize("a_raw", [1, 7, 100, 512, 2048, 4000, 4095])
@pytest.mark.parametrize("n", [1, 2, 17, 256])
def test_uniform_slab_within_bound(a_raw: int, n: int) -> None:
    a = a_raw / 4096
    acc = run_ftb(np.full((n, 1, 3), 4096), np.full((n, 1), a_raw))
    exact = 1.0 - (1.0 - a) ** n
    bound_a = min(n, 1.0 / a) * H  # derivation: docs/units/composite-crop-skew.md
    assert abs(acc[0, 3] / ONE - exact) <= bound_a
    assert abs(acc[0, 0] / ONE - exact) <= 3 * n * H
    assert (acc[0, :3] <= acc[0, 3]).all()


def test_random_rays_within_bound(rng: np.random.Generator) -> None:
    n, rays = 200, 64
    alpha = rng.integers(0, 4097, (n, rays)) * (rng.random((n, rays)) < 0.3)
    rgb = rng.integers(0, 4097, (n, rays, 3))
    acc = run_ftb(rgb, alpha)
    gold = golden_ftb(rgb / 4096, alpha / 4096)
    ba, bc = cu.ftb_error_bound(n, CFG)
    assert np.abs(acc[:, 3] / ONE - gold[:, 3]).max() <= ba
    assert np.abs(acc[:, :3] / ONE - gold[:, :3]).max() <= bc
    assert (acc[:, :3] <= acc[:, 3:4]).all() and (acc <= ONE).all()


@pytest.mark.extremes
def test_many_low_alpha_samples_stall_exactly() -> None:
    """4096 samples of alpha = 1/4096: within the bound of 1 - (1-a)^n; later the opacity
    stalls exactly where (1 - A)_raw * a_raw < 2048, i.e. A = 1 - 2047 * 2**-16."""
    n = 4096
    acc = run_ftb(np.full((n, 1, 3), 4096), np.full((n, 1), 1))
    exact = 1.0 - (1.0 - 1 / 4096) ** n
    assert abs(acc[0, 3] / ONE - exact) <= 4096 * H
    # continue from A = 1 - 2100 LSB: 53 more samples each remove one LSB, then nothing
    acc = np.array([[0, 0, 0, ONE - 2100]], dtype=np.int64)
    trace = []
    for _ in range(1100):
        cu.front_to_back(acc, np.array([0]), np.array([[4096, 0, 0]]), np.array([1]))
        trace.append(int(acc[0, 3]))
    trace = np.array(trace)
    assert trace[52] == ONE - 2047 and (trace[52:] == ONE - 2047).all()
    assert (np.diff(trace) >= 0).all()
    # the float opacity keeps rising; the fixed one is stuck below it
    assert 1 - (1 - 1 / 4096) ** 1100 * 2100 / ONE > trace[-1] / ONE


@pytest.mark.extremes
@pytest.mark.parametrize("a_raw", [1, 3, 64, 2047])
def test_stall_point_formula(a_raw: int) -> None:
    """Stall: w = 0 exactly when T_raw * a_raw < 2048 (nearest-up of T a / 4096)."""
    t_stall = -(-2048 // a_raw) - 1  # largest T with T * a < 2048
    acc = np.array([[0, 0, 0, ONE - t_stall], [0, 0, 0, ONE - t_stall - 1]], dtype=np.int64)
    before = acc.copy()
    cu.front_to_back(acc, np.arange(2), np.full((2, 3), 4096), np.full(2, a_raw))
    assert (acc[0] == before[0]).all()
    assert acc[1, 3] > before[1, 3]


@pytest.mark.extremes
def test_alpha_below_lsb_after_correction_vanishes() -> None:
    """alpha = 1/4096 with k = 1/4 (supersampling 4): 1-(1-a)^k ~ 2**-14 < 2**-13 rounds to
    0, so 2048 such samples leave the accumulator at exactly 0 (the float ray reaches
    1 - (1 - 2**-14)**2048 = 0.118)."""
    a = cu.correct_opacity(np.full(2048, 1), 0.25)
    assert (a == 0).all()
    acc = run_ftb(np.full((2048, 1, 3), 4096), a[:, None])
    assert (acc == 0).all()
    # k = 1/2: 4096 (1 - (1 - 1/4096)**0.5) = 0.50003 rounds up to 1
    assert cu.correct_opacity(np.array([1]), 0.5)[0] == 1


@pytest.mark.extremes
def test_alpha_zero_and_one() -> None:
    acc = np.array([[100, 200, 300, 1000]], dtype=np.int64)
    before = acc.copy()
    cu.front_to_back(acc, np.array([0]), np.array([[4096, 4096, 4096]]), np.array([0]))
    assert (acc == before).all()
    acc[:] = 0
    cu.front_to_back(acc, np.array([0]), np.array([[4096, 2048, 0]]), np.array([4096]))
    assert acc.tolist() == [[ONE, ONE // 2, 0, ONE]]
    assert cu.terminated(acc, 0.95).all()
    assert not cu.terminated(acc, 1.0).any()  # 1.0 disables ERT
    cu.front_to_back(acc, np.array([0]), np.array([[4096, 4096, 4096]]), np.array([4096]))
    assert acc.tolist() == [[ONE, ONE // 2, 0, ONE]]


def test_ert_threshold_quantised_nearest_up() -> None:
    thr = 0.95
    q = int(np.floor(thr * ONE + 0.5))
    acc = np.zeros((3, 4), dtype=np.int64)
    acc[:, 3] = [q - 1, q, q + 1]
    assert cu.terminated(acc, thr).tolist() == [False, True, True]
    assert cu.terminated(acc, 0.0).all()


@pytest.mark.extremes
@pytest.mark.parametrize("k", [0.125, 0.5, 1.0, 2.0, 8.0])
def test_correction_table(k: float) -> None:
    k_raw = int(np.floor(k * 256 + 0.5))
    t = cu.correction_table(k_raw)
    assert t.shape == (4097,) and t[0] == 0 and t[4096] == 4096
    assert (np.diff(t) >= 0).all()
    a = np.arange(4097) / 4096
    assert np.abs(t / 4096 - (1 - (1 - a) ** k)).max() <= 2.0**-13 + 1e-12
    if k == 1.0:
        assert (t == np.arange(4097)).all()
    with pytest.raises(ValueError):
        t[3] = 0  # read-only ROM


def test_correct_opacity_per_ray_k(rng: np.random.Generator) -> None:
    alpha = rng.integers(0, 4097, 1000)
    k = rng.choice([0.5, 1.0, 2.0, 8.0], 1000)
    out = cu.correct_opacity(alpha, k)
    for kv in (0.5, 1.0, 2.0, 8.0):
        m = k == kv
        assert (out[m] == cu.correct_opacity(alpha[m], kv)).all()
    with pytest.raises(ValueError):
        cu.correct_opacity(alpha, 0.0)


@pytest.mark.extremes
def test_saturation_counted_never_wraps() -> None:
    SATURATIONS.clear()
    acc = np.array([[ONE - 1, 0, 0, ONE - 1]], dtype=np.int64)
    cu.front_to_back(acc, np.array([0]), np.array([[5000, 0, 0]]), np.array([5000]))
    assert acc.tolist() == [[ONE, 0, 0, ONE]]  # inputs clipped to 1.0, never past it
    assert SATURATIONS["composite.alpha"] == 2 and "composite.acc" not in SATURATIONS
    out = cu.to_output(np.array([[ONE + 5, 0, 0, 1 << 17]], dtype=np.int64))  # corrupt state
    assert out.tolist() == [[255, 0, 0, 255]] and SATURATIONS["composite.acc"] == 2
    big = np.array([(1 << 48) - 10], dtype=np.int64)
    cu.xray(big, np.array([0, 0]), np.array([1 << 20, 1 << 20]), 200.0)
    assert big[0] == (1 << 48) - 1 and SATURATIONS["composite.xray"] == 1


@given(
    st.lists(st.integers(0, 4096), min_size=1, max_size=40),
    st.lists(st.integers(0, 4096), min_size=1, max_size=40),
)
@settings(deadline=None, max_examples=200)
def test_back_to_front_matches_float(alphas: list[int], colours: list[int]) -> None:
    n = min(len(alphas), len(colours))
    a, c = np.array(alphas[:n]), np.array(colours[:n])
    acc = np.zeros((1, 4), dtype=np.int64)
    ref = np.zeros(4)
    for ai, ci in zip(a[::-1], c[::-1], strict=True):  # farthest first
        cu.back_to_front(acc, np.array([0]), np.array([[ci, ci, ci]]), np.array([ai]))
        af, cf = ai / 4096, ci / 4096
        ref[:3] = af * cf + (1 - af) * ref[:3]
        ref[3] = af + (1 - af) * ref[3]
    assert np.abs(acc[0] / ONE - ref).max() <= n * H
    assert (acc <= ONE).all()


def test_mip_minip_repeats() -> None:
    acc = np.full(3, -1, dtype=np.int64)
    cu.mip(acc, np.array([0, 0, 2]), np.array([5, 9, 3]))
    assert acc.tolist() == [9, -1, 3]
    acc = np.full(3, 1 << 20, dtype=np.int64)
    cu.minip(acc, np.array([1, 1]), np.array([7, 4]))
    assert acc.tolist() == [1 << 20, 4, 1 << 20]


def test_xray_against_float(rng: np.random.Generator) -> None:
    s = rng.integers(0, 4096 << 4, 500)
    dt = rng.uniform(0.1, 3.0, 500)
    rays = rng.integers(0, 10, 500)
    acc = np.zeros(10, dtype=np.int64)
    cu.xray(acc, rays, s, dt)
    fmt = CFG.xray_acc
    gold = np.bincount(rays, weights=(s / 16) * dt, minlength=10)
    bound = np.bincount(rays, weights=s / 16, minlength=10) * 2.0**-13
    assert (np.abs(fmt.to_float(acc) - gold) <= bound + 1e-9).all()
    with pytest.raises(ValueError):
        cu.xray(acc, rays, s, -1.0)


def test_iso_hit() -> None:
    assert cu.iso_hit(np.array([1, 5, 6]), 5).tolist() == [False, True, True]


@pytest.mark.extremes
@pytest.mark.parametrize("bits", [8, 12])
def test_output(bits: int) -> None:
    cfg = cu.CompositeConfig(output_bits=bits)
    acc = np.array([[ONE, 0, ONE // 2, ONE]], dtype=np.int64)
    out = cu.to_output(acc, cfg)
    top = (1 << bits) - 1
    assert out.tolist() == [[top, 0, (top + 1) // 2, top]]
    vals = np.arange(ONE + 1, dtype=np.int64)
    f = cu.output_to_float(cu.to_output(vals[:, None], cfg), cfg)[:, 0]
    assert np.abs(f - vals / ONE).max() <= 0.5 / top + 1e-12
    assert f.min() == 0.0 and f.max() == 1.0


def test_config_rejects_bad_widths() -> None:
    with pytest.raises(ValueError):
        cu.CompositeConfig(acc_frac_bits=8)
    with pytest.raises(ValueError):
        cu.correction_table(0)
