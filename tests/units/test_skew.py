"""Skewed memory: conflict-free beams, address bijections, mini-block properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models.units import skew as sk

pytestmark = pytest.mark.model

PS = [1, 2, 3, 4, 5, 8, 16]
SIZES = [1, 2, 3, 7, 16, 33, 64, 100]


def grid(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z, y, x = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    return x.ravel(), y.ravel(), z.ravel()


@pytest.mark.parametrize("P", PS)
@pytest.mark.parametrize("n", SIZES)
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_beams_conflict_free(P: int, n: int, axis: int) -> None:
    assert sk.beam_is_conflict_free(P, n, axis)


@pytest.mark.parametrize("P", [2, 3, 5])
def test_brute_force_every_beam(P: int) -> None:
    """Independent check on every beam of a 9^3 volume, all three axes."""
    n = 9
    x, y, z = grid(n)
    mod = sk.cube4_module(x, y, z, P).reshape(n, n, n)  # (z, y, x)
    for ax in (0, 1, 2):
        m = np.moveaxis(mod, ax, -1)
        runs = np.lib.stride_tricks.sliding_window_view(m, P, axis=-1)
        assert (np.sort(runs, axis=-1)[..., 1:] != np.sort(runs, axis=-1)[..., :-1]).all()


@pytest.mark.parametrize("P", PS)
@pytest.mark.parametrize("n", [1, 3, 4, 6, 8, 10, 16])
def test_cube4_bijection(P: int, n: int) -> None:
    x, y, z = grid(n)
    m, a = sk.cube4_module(x, y, z, P), sk.cube4_address(x, y, z, n, P)
    pairs = m * (a.max() + 1) + a
    assert np.unique(pairs).size == x.size
    words = -(-n // P) * P * n * n // P
    assert a.min() >= 0 and a.max() < words
    back = sk.cube4_voxel(m, a, n, P)
    for got, want in zip(back, (x, y, z), strict=True):
        assert (got == want).all()


def test_cube4_aligned_x_run_shares_one_address() -> None:
    """architectures.md 1.2: with P | n an aligned x-run of P voxels has one address."""
    n, P = 16, 4
    x = np.arange(8, 12)
    a = sk.cube4_address(x, np.full(4, 3), np.full(4, 5), n, P)
    assert len(set(a.tolist())) == 1
    assert sorted(sk.cube4_module(x, 3, 5, P).tolist()) == [0, 1, 2, 3]


@pytest.mark.extremes
@given(st.integers(0, 1023), st.integers(0, 1023), st.integers(0, 1023), st.sampled_from(PS))
@settings(deadline=None, max_examples=300)
def test_cube4_1024_cubed_no_overflow(x: int, y: int, z: int, P: int) -> None:
    """Cube-4's 1024^3 (architectures.md 1.1 / 9.4 row 7): int32 inputs are widened."""
    n = 1024
    xi, yi, zi = (np.array([v], dtype=np.int32) for v in (x, y, z))
    a = sk.cube4_address(xi, yi, zi, n, P)
    assert a.dtype == np.int64 and 0 <= a[0] < n**3 // P + n * n
    assert a[0] == ((z * n + y) * (-(-n // P) * P) + x) // P  # Python ints: no overflow
    back = sk.cube4_voxel(sk.cube4_module(xi, yi, zi, P), a, n, P)
    assert [int(v[0]) for v in back] == [x, y, z]


@pytest.mark.extremes
def test_cube4_corner_of_2048_cubed() -> None:
    """z n^2 = 2**33 overflows int32; the model works in int64."""
    n, P = 2048, 16
    c = np.array([n - 1], dtype=np.int32)
    a = sk.cube4_address(c, c, c, n, P)
    assert a[0] == (n**3 - 1) // P


@pytest.mark.parametrize("modules,banks", [(4, 4), (4, 2), (2, 4), (1, 1), (3, 2)])
@pytest.mark.parametrize("n", [2, 5, 8, 12])
def test_vp500_bijection(modules: int, banks: int, n: int) -> None:
    x, y, z = grid(n)
    m, b, a = sk.vp500_miniblock(x, y, z, n, modules, banks)
    assert m.min() >= 0 and m.max() < modules and b.min() >= 0 and b.max() < banks
    key = (a * banks + b) * modules + m
    assert np.unique(key).size == x.size
    back = sk.vp500_voxel(m, b, a, n, modules, banks)
    for got, want in zip(back, (x, y, z), strict=True):
        assert (got == want).all()


@pytest.mark.parametrize("n", [8, 16, 20])
def test_miniblock_lives_in_one_module_and_bank(n: int) -> None:
    x, y, z = grid(n)
    m, b, a = sk.vp500_miniblock(x, y, z, n)
    blk = ((z >> 1) * n + (y >> 1)) * n + (x >> 1)
    for v in (m, b, a >> 3):
        order = np.argsort(blk, kind="stable")
        per = v[order].reshape(-1, 8)
        assert (per == per[:, :1]).all()
    assert np.unique(a & 7).tolist() == list(range(8))  # one burst of 8 per block


@pytest.mark.parametrize("modules,banks", [(4, 4), (4, 2), (2, 2)])
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_consecutive_miniblocks_alternate(modules: int, banks: int, axis: int) -> None:
    """Adjacent mini-blocks along an axis sit in different modules; the next mini-block
    the same module receives along the axis (M blocks on) is in the next bank."""
    n = 64
    rng = np.random.default_rng(7)
    v = rng.integers(0, n - 2 * modules - 2, (3, 2000))
    step = np.zeros((3, 1), dtype=np.int64)
    step[axis] = 2
    m0, b0, _ = sk.vp500_miniblock(*v, n, modules, banks)
    m1, b1, _ = sk.vp500_miniblock(*(v + step), n, modules, banks)
    if modules > 1:
        assert (m0 != m1).all()
    mM, bM, _ = sk.vp500_miniblock(*(v + modules * step), n, modules, banks)
    assert (mM == m0).all()
    assert (bM == (b0 + 1) % banks).all()
    if banks > 1:
        assert (bM != b0).all()


@pytest.mark.extremes
def test_vp500_largest_volume() -> None:
    """256^3 is VolumePro 500's largest one-pass volume (RTViz FAQ, architectures.md 3):
    16-bit voxels fill 32 MB, each (module, bank) holds exactly 2**20 voxels."""
    cfg = sk.SkewConfig()
    n = cfg.max_size
    rng = np.random.default_rng(3)
    x, y, z = rng.integers(0, n, (3, 200000))
    x[:2], y[:2], z[:2] = [0, n - 1], [0, n - 1], [0, n - 1]
    m, b, a = sk.vp500_miniblock(x, y, z, n, cfg.modules, cfg.banks)
    assert a.max() < n**3 // (cfg.modules * cfg.banks)
    back = sk.vp500_voxel(m, b, a, n, cfg.modules, cfg.banks)
    assert all((g == w).all() for g, w in zip(back, (x, y, z), strict=True))
    assert n**3 * 2 <= 128 << 20  # fits the smaller 128 MB board


def test_bad_axis() -> None:
    with pytest.raises(ValueError):
        sk.beam_is_conflict_free(4, 8, 3)
