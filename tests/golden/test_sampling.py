"""Reconstruction filters against an independent sampler and the Marschner-Lobb signal."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from hwsim.golden import gradient_at_voxels, taps, trilinear, trilinear_rows, voxel_gradients
from hwsim.golden.sampling import sample, sample_gradients
from hwsim.volumes import make_phantom, marschner_lobb

pytestmark = pytest.mark.golden


@pytest.mark.parametrize("shape", [(7, 8, 9), (16, 16, 16), (1, 5, 6), (2, 1, 3)])
def test_trilinear_agrees_with_scipy_map_coordinates(shape, rng):
    data = rng.normal(size=shape)
    # Points across the whole box, including the half voxel beyond the outer centres.
    pts = rng.uniform(-0.5, np.array(shape) - 0.5, size=(5000, 3))
    ours = trilinear(data, pts)
    theirs = ndimage.map_coordinates(data, pts.T, order=1, mode="nearest")
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12)


def test_filters_reproduce_voxel_values_at_voxel_centres(rng):
    data = rng.normal(size=(6, 7, 8))
    centres = np.argwhere(np.ones(data.shape, bool)).astype(np.float64)
    for kind in ("nearest", "trilinear", "cubic"):
        got = sample(data.ravel(), taps(centres, data.shape, kind))
        np.testing.assert_allclose(got, data.ravel(), atol=1e-12, err_msg=kind)


def test_nearest_rounds_half_up():
    data = np.arange(4, dtype=np.float64).reshape(1, 1, 4)
    got = sample(
        data.ravel(),
        taps(np.array([[0, 0, 0.5], [0, 0, 1.49], [0, 0, 2.5]]), data.shape, "nearest"),
    )
    np.testing.assert_array_equal(got, [1, 1, 3])


def test_marschner_lobb_reconstruction_error():
    """RMS error of trilinear reconstruction on the 40^3 lattice against the analytic
    signal, over a fine 121^3 grid of the whole [-1, 1]^3 domain.

    The signal (range [0, 1]) has a radial term of amplitude alpha / (2 (1 + alpha)) =
    0.1 at f_M = 6, close to the lattice's Nyquist frequency (19.5 / 2 cycles per unit).
    Trilinear attenuates it by sinc^2 (f / f_s) per axis and aliases the rest: a filter
    that dropped the term entirely would leave 0.1 / sqrt(2) = 0.07 RMS, a perfect one 0.
    So the error must lie between 1% and 7% of the range (measured: 0.036).  Cubic must
    do better and nearest worse (100 000 random points: cubic taps are 64 per point).
    """
    volume = make_phantom("marschner-lobb", size=40)
    flat = volume.data.astype(np.float64).ravel()
    axis = np.linspace(-1, 1, 121)
    z, y, x = (c.ravel() for c in np.meshgrid(axis, axis, axis, indexing="ij"))
    idx = (np.stack([z, y, x], axis=1) + 1) / (2 / 39)
    error = trilinear(volume.data, idx) - marschner_lobb(x, y, z)
    rms = float(np.sqrt(np.mean(error**2)))
    print(f"Marschner-Lobb trilinear RMS error on 40^3 (121^3 grid): {rms:.4f}")
    assert 0.01 < rms < 0.07

    rng = np.random.default_rng(7)
    xyz = rng.uniform(-1, 1, size=(100_000, 3))
    idx = (xyz[:, ::-1] + 1) / (2 / 39)
    truth = marschner_lobb(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    by_kind = {
        kind: float(np.sqrt(np.mean((sample(flat, taps(idx, volume.shape, kind)) - truth) ** 2)))
        for kind in ("nearest", "trilinear", "cubic")
    }
    print("Marschner-Lobb RMS error on 40^3 (random points):", by_kind)
    assert by_kind["cubic"] < by_kind["trilinear"] < by_kind["nearest"]
    assert abs(by_kind["trilinear"] - rms) < 0.1 * rms  # the two estimates agree


def test_voxel_gradients_are_exact_for_a_linear_ramp_in_world_units():
    z, y, x = np.meshgrid(np.arange(5.0), np.arange(6.0), np.arange(7.0), indexing="ij")
    spacing = (2.0, 0.5, 1.0)
    data = 3 * x * spacing[2] - 2 * y * spacing[1] + 0.5 * z * spacing[0]
    gx, gy, gz = voxel_gradients(data, spacing)
    np.testing.assert_allclose([gx.mean(), gy.mean(), gz.mean()], [3, -2, 0.5])
    np.testing.assert_allclose(np.ptp(gx) + np.ptp(gy) + np.ptp(gz), 0, atol=1e-12)
    pts = np.array([[2.0, 2.5, 3.25]])
    g = sample_gradients(data.ravel(), pts, data.shape, spacing, "trilinear")
    np.testing.assert_allclose(g[0], [3, -2, 0.5])
    assert voxel_gradients(np.ones((1, 3, 3)), (1, 1, 1))[2].max() == 0  # 1-voxel axis


def test_interleaved_rows_match_per_field_taps(rng):
    data = rng.normal(size=(5, 1, 7))
    spacing = (1.0, 2.0, 0.5)
    rows = np.column_stack([data.ravel(), *gradient_at_voxels(data, spacing)])
    pts = rng.uniform(-0.5, np.array(data.shape) - 0.5, size=(2000, 3))
    got = trilinear_rows(np.ascontiguousarray(rows), data.shape, pts)
    t = taps(pts, data.shape, "trilinear")
    want = np.column_stack([sample(np.ascontiguousarray(c), t) for c in rows.T])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert gradient_at_voxels is voxel_gradients
