"""Shading unit model against float64 Phong, per sample and through reflectance maps.

The bound is assembled from the terms ``models/units/shade.py`` documents: each dot
product off by at most ``3 * 2**-F`` plus a rounding; ``x**n`` amplifying that by up to
``n`` and the specular table's index adding ``n / (2 entries)``; ``2**-9`` for each UQ4.8
coefficient and intensity; ``2**-13`` per rounding to UQ1.12 / UQ4.12.  Reflectance maps
add the cube-map cell's angle (``sqrt(2) / map_size``) times ``kd I`` and ``ks I n``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from models.units import shade as su

pytestmark = pytest.mark.model

ONE = 4096
R13 = 2.0**-13  # one rounding to 12 fraction bits
Q9 = 2.0**-9  # one UQ4.8 quantisation


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def float_phong(c, n, lights, view, material):
    """``clamp(ka c + sum I (kd max(N.L, 0) c + ks max(N.H, 0)**n), 0, 1)``."""
    ka, kd, ks, shininess = material
    out = ka * c
    for direction, intensity in lights:
        h = unit(direction + view)
        ndl = np.maximum(n @ direction, 0.0)[:, None]
        ndh = np.maximum(n @ h, 0.0)[:, None]
        out = out + intensity * (kd * ndl * c + ks * ndh**shininess)
    return np.clip(out, 0.0, 1.0)


def phong_bound(c, lights, material, cfg):
    ka, kd, ks, shininess = material
    e_dot = 3 * 2.0**-cfg.normal_frac_bits + R13
    bound = Q9 * c + R13  # ambient coefficient and its rounding
    for _, intensity in lights:
        bound = bound + intensity * kd * c * e_dot + Q9 * (intensity + kd) * c + 3 * R13
        table = shininess * (e_dot + 1 / (2 * cfg.spec_table_entries)) + R13
        bound = bound + intensity * ks * table + Q9 * (intensity + ks) + 2 * R13
    return bound


def case(rng, n_samples, n_lights):
    normals = unit(rng.normal(size=(n_samples, 3)))
    colours = rng.integers(0, ONE + 1, (n_samples, 3))
    lights = [(unit(rng.normal(size=3)), float(rng.uniform(0.2, 1.5))) for _ in range(n_lights)]
    return normals, colours, lights


def shade_fixed(sh, colours, normals):
    f = sh.cfg.normal_frac_bits
    q = np.floor(normals * (1 << f) + 0.5).astype(np.int64)  # the gradient unit's SQ1.F
    return su.shade(sh, colours, q) / ONE


@pytest.mark.parametrize("n_lights", [1, 2, 3])
@pytest.mark.parametrize("material", [(0.1, 0.7, 0.3, 10.0), (0.3, 0.5, 0.6, 40.0)])
def test_phong_within_the_documented_bound(rng, n_lights, material):
    cfg = su.ShadeConfig()
    normals, colours, lights = case(rng, 4000, n_lights)
    view = np.array([0.0, 0.0, 1.0])
    sh = su.setup(lights, view, material, cfg)
    got = shade_fixed(sh, colours, normals)
    want = float_phong(colours / ONE, normals, lights, view, material)
    assert (np.abs(got - want) <= phong_bound(colours / ONE, lights, material, cfg)).all()


@settings(max_examples=150, deadline=None)
@given(
    st.integers(4, 16),
    st.sampled_from([16, 256, 4096]),
    st.floats(1.0, 60.0),
    st.integers(0, 2**32 - 1),
)
def test_phong_bound_across_widths(f, entries, shininess, seed):
    cfg = su.ShadeConfig(normal_frac_bits=f, spec_table_entries=entries)
    normals, colours, lights = case(np.random.default_rng(seed), 200, 2)
    material = (0.2, 0.6, 0.5, shininess)
    view = np.array([0.3, -0.2, 1.0])
    view = view / np.linalg.norm(view)
    sh = su.setup(lights, view, material, cfg)
    got = shade_fixed(sh, colours, normals)
    want = float_phong(colours / ONE, normals, lights, view, material)
    assert (np.abs(got - want) <= phong_bound(colours / ONE, lights, material, cfg)).all()


@pytest.mark.parametrize("map_size", [16, 64, 256])
def test_reflectance_maps_within_phong_plus_the_cell_angle(rng, map_size):
    cfg = su.ShadeConfig(method="reflectance-map", map_size=map_size)
    material = (0.1, 0.7, 0.3, 10.0)
    normals, colours, lights = case(rng, 4000, 2)
    view = np.array([0.0, 0.0, 1.0])
    sh = su.setup(lights, view, material, cfg)
    got = shade_fixed(sh, colours, normals)
    want = float_phong(colours / ONE, normals, lights, view, material)
    c = colours / ONE
    angle = np.sqrt(2) / map_size + 2.0**-cfg.normal_frac_bits  # cell, and the quantised N
    _, kd, ks, shininess = material
    extra = sum(i * (kd * c + ks * shininess) * angle for _, i in lights)
    assert (np.abs(got - want) <= phong_bound(c, lights, material, cfg) + extra).all()


@pytest.mark.parametrize("method", ["phong", "reflectance-map"])
def test_the_zero_normal_gets_ambient_light_only(rng, method):
    cfg = su.ShadeConfig(method=method)
    material = (0.25, 0.7, 0.9, 8.0)
    sh = su.setup([(unit([0.2, 0.3, 1.0]), 1.0)], np.array([0.0, 0.0, 1.0]), material, cfg)
    colours = rng.integers(0, ONE + 1, (50, 3))
    got = su.shade(sh, colours, np.zeros((50, 3), dtype=np.int64))
    ka = int(np.floor(0.25 * 256 + 0.5))
    assert (got == (ka * colours + 128) // 256).all()


def test_the_specular_table_runs_from_zero_to_one():
    sh = su.setup(
        [(unit([0, 0, 1]), 1.0)], np.array([0.0, 0.0, 1.0]), (0, 1, 1, 20.0), su.ShadeConfig()
    )
    assert sh.spec[0] == 0 and sh.spec[-1] == ONE and (np.diff(sh.spec) >= 0).all()


def test_a_light_head_on_at_full_strength_saturates_exactly():
    view = np.array([0.0, 0.0, 1.0])
    sh = su.setup([(view, 1.0)], view, (0.0, 1.0, 1.0, 5.0), su.ShadeConfig())
    normal = np.array([[0, 0, 1 << sh.cfg.normal_frac_bits]])
    assert (su.shade(sh, np.array([[ONE, ONE, ONE]]), normal) == ONE).all()  # clamped at 1


def test_reflectance_maps_need_one_view_direction():
    cfg = su.ShadeConfig(method="reflectance-map")
    views = np.tile([0.0, 0.0, 1.0], (4, 1))  # perspective: one per sample
    with pytest.raises(ValueError, match="one view direction"):
        su.setup([(unit([0, 0, 1]), 1.0)], views, (0.1, 0.7, 0.3, 10.0), cfg)


def test_config_out_of_range_is_refused():
    with pytest.raises(ValueError, match="phong \\| reflectance-map"):
        su.ShadeConfig(method="gouraud")
    with pytest.raises(ValueError, match="map_size 2..1024"):
        su.ShadeConfig(map_size=1)


def test_golden_reflectance_maps_shade_at_the_units_cell_centres(rng):
    """The golden renderer's float64 reflectance maps (hwsim.golden.shading) pick the cell
    the unit picks for the same normal, up to the SQ1.F quantisation of normals that sit
    on a cell edge: then a neighbouring cell, never farther."""
    from hwsim.golden.shading import cube_map_normals

    size, f = 64, 10
    n = rng.normal(size=(20000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    golden = cube_map_normals(n, size)
    q = np.floor(n * (1 << f) + 0.5).astype(np.int64)
    centres = su._cell_normals(size)[su._cell_index(q, size)]
    angle = np.arccos(np.clip(np.sum(golden * centres, axis=1), -1, 1))
    same = np.abs(golden - centres).max(axis=1) < 1e-12
    assert same.mean() > 0.97
    assert angle.max() <= 2.5 * np.sqrt(2) / size  # a neighbouring cell at most
    assert np.array_equal(cube_map_normals(np.zeros((2, 3)), size), np.zeros((2, 3)))


@pytest.mark.parametrize("method", ["phong", "reflectance-map"])
def test_illumination_modulation_scales_the_light_not_the_ambient(rng, method):
    """GMIM: a factor of one changes nothing, zero leaves ambient light only, and a factor
    in between scales diffuse plus specular within two roundings per term."""
    cfg = su.ShadeConfig(method=method, map_size=32)
    normals, colours, lights = case(rng, 3000, 2)
    material = (0.2, 0.6, 0.4, 16.0)
    sh = su.setup(lights, unit(np.array([0.2, -0.3, 1.0])), material, cfg)
    q = np.floor(normals * (1 << cfg.normal_frac_bits) + 0.5).astype(np.int64)
    plain = su.shade(sh, colours, q)
    assert np.array_equal(su.shade(sh, colours, q, np.full(3000, ONE)), plain)
    ambient = su.shade_raw(sh.ka, colours, 0, 0)
    assert np.array_equal(su.shade(sh, colours, q, np.zeros(3000, np.int64)), ambient)
    f = rng.integers(0, ONE + 1, 3000)
    half = su.shade(sh, colours, q, f)
    expect = np.clip(ambient + (plain - ambient) * (f[:, None] / ONE), 0, ONE)
    lit = plain < ONE  # where the unmodulated colour saturated, the light term is unknown
    assert np.abs(half - expect)[lit].max() <= 3
