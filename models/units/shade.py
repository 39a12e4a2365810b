"""Shading: Phong per sample, or diffuse and specular reflectance maps (VolumePro 500).

# Ref: architectures.md section 3 (reflectance maps: a diffuse and a specular map looked
#      up by gradient direction, any number of lights) and 5 (per-sample Phong, VIZARD II);
#      Phong 1975, Blinn 1977.

``colour = clamp(ka c + sum_l I_l (kd max(N.L, 0) c + ks spec(max(N.H, 0))), 0, 1)`` with
``spec(x) = x**n`` from a table, white specular light, in UQ1.12.  Light and half vectors
are SQ1.F like the normals; coefficients and intensities UQ4.8.  ``N = 0`` (a zero
gradient) gives exactly ``ka c``.

Phong error against float64: each dot product is off by at most ``3 * 2**-F`` (normal
and light quantisation) plus a rounding; ``x**n`` amplifies that by up to ``n`` near
``x = 1`` and the table index adds ``n / (2 entries)``; coefficient quantisation adds
``2**-9`` each.  Reflectance maps replace ``N`` by the centre of its cube-map cell: an
angle of up to ``sqrt(2) / map_size`` radians, so diffuse moves by up to ``kd I`` times
that and specular by ``ks I n`` times that.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from hwsim.numerics import round_shift_raw

__all__ = [
    "ShadeConfig",
    "Shader",
    "setup",
    "shade",
    "light_terms_raw",
    "cell_index_raw",
    "shade_raw",
    "LATENCY",
    "II",
]

#: Cycles: the RTL's stage plan (rtl/shade.py STAGES), pipelined so every stage meets a
#: 125 MHz clock at 0.35 um by the project's depth estimate (issue 34: the reflectance-map
#: cell dividers over 4 stages, the combine's products and sum apart; the Phong method
#: fills the same stages).  architectures.md 9.3's "shader 3-5" [I] held only as a
#: 125-gate-deep block (~42 MHz).
LATENCY = 10
II = 1
ONE = 1 << 12
_COEF = 8


@dataclass(frozen=True, kw_only=True)
class ShadeConfig:
    """Shading method and widths."""

    method: str = "phong"
    normal_frac_bits: int = 10
    spec_table_entries: int = 1024
    map_size: int = 64

    def __post_init__(self) -> None:
        if self.method not in ("phong", "reflectance-map"):
            raise ValueError("shade.method: phong | reflectance-map")
        if not 4 <= self.spec_table_entries <= 65536 or not 2 <= self.map_size <= 1024:
            raise ValueError("shade: spec_table_entries 4..65536, map_size 2..1024")


@dataclass(frozen=True)
class Shader:
    """Host-quantised lighting state."""

    cfg: ShadeConfig
    light: np.ndarray  # (k, 3) SQ1.F
    half: np.ndarray  # (k, 3) or (n, k, 3) SQ1.F
    intensity: np.ndarray  # (k,) UQ4.8
    ka: int
    kd: int
    ks: int
    spec: np.ndarray  # (entries + 1,) UQ1.12
    maps: tuple[np.ndarray, np.ndarray] | None  # diffuse, specular (6*R*R + 1,) UQ4.12


def _q(x: np.ndarray | float, bits: int) -> np.ndarray:
    return np.floor(np.asarray(x, dtype=np.float64) * (1 << bits) + 0.5).astype(np.int64)


def setup(
    lights: list[tuple[np.ndarray, float]],
    toward_viewer: np.ndarray,
    material: tuple[float, float, float, float],
    cfg: ShadeConfig,
) -> Shader:
    """Quantise lights, half vectors, coefficients; build the specular table and maps."""
    f = cfg.normal_frac_bits
    ka, kd, ks, shininess = material
    dirs = np.array([np.asarray(d, dtype=np.float64) for d, _ in lights]).reshape(-1, 3)
    v = np.asarray(toward_viewer, dtype=np.float64)
    h = dirs + (v[..., None, :] if v.ndim == 2 else v)
    norm = np.linalg.norm(h, axis=-1, keepdims=True)
    h = np.divide(h, norm, out=np.zeros_like(h), where=norm > 1e-12)
    x = np.arange(cfg.spec_table_entries + 1) / cfg.spec_table_entries
    spec = _q(x**shininess, 12)
    shader = Shader(
        cfg,
        _q(dirs, f),
        _q(h, f),
        _q([i for _, i in lights], _COEF),
        int(_q(ka, _COEF)),
        int(_q(kd, _COEF)),
        int(_q(ks, _COEF)),
        spec,
        None,
    )
    if cfg.method == "reflectance-map":
        if v.ndim == 2:
            raise ValueError("reflectance maps need one view direction (parallel projection)")
        d, s = _lighting_terms(shader, _map_normals(cfg.map_size, f), shader.half)
        shader = Shader(**{**shader.__dict__, "maps": (d, s)})
    return shader


@functools.lru_cache(maxsize=8)
def _map_normals(r: int, f: int) -> np.ndarray:
    """The SQ1.``f`` normals a reflectance map is computed at: its cells' centres
    (:func:`_cell_normals`), then the zero normal; the same for every frame of a map
    size and normal width, so computed once (read-only)."""
    q = _q(np.vstack([_cell_normals(r), np.zeros((1, 3))]), f)
    q.flags.writeable = False
    return q


def _cell_normals(r: int) -> np.ndarray:
    """Unit normals at the centres of a cube map's cells: face-major, row, column."""
    c = (np.arange(r) + 0.5) / r * 2 - 1
    u, w = np.meshgrid(c, c, indexing="ij")
    out = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            p = np.empty((r, r, 3))
            p[..., axis] = sign
            others = [a for a in range(3) if a != axis]
            p[..., others[0]], p[..., others[1]] = u, w
            out.append(p.reshape(-1, 3))
    n = np.vstack(out)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _cell_index(normals: np.ndarray, r: int) -> np.ndarray:
    """Cube-map cell of each SQ1.F normal ``(n, 3)``; the zero normal maps to the last
    entry."""
    n = np.asarray(normals, dtype=np.int64)
    return cell_index_raw(n[:, 0], n[:, 1], n[:, 2], r)


def _lighting_terms(sh: Shader, normals: np.ndarray, half: np.ndarray):
    """Diffuse factor and specular term (both UQ4.12) of SQ1.F normals."""
    f = sh.cfg.normal_frac_bits
    normals = np.asarray(normals, dtype=np.int64)
    nx, ny, nz = normals[:, 0], normals[:, 1], normals[:, 2]
    diffuse = np.zeros(normals.shape[0], dtype=np.int64)
    specular = np.zeros(normals.shape[0], dtype=np.int64)
    for k in range(sh.light.shape[0]):
        hk = half[:, k] if half.ndim == 3 else half[k]
        (lx, ly, lz), (hx, hy, hz) = sh.light[k], hk.T
        e = sh.cfg.spec_table_entries
        d, si = light_terms_raw(nx, ny, nz, lx, ly, lz, hx, hy, hz, sh.intensity[k], sh.kd, e, f)
        s = specular_raw(sh.intensity[k], sh.ks, sh.spec[si])
        diffuse += d
        specular += s
    return diffuse, specular


def shade(
    sh: Shader, rgb: np.ndarray, normals: np.ndarray, illumination: np.ndarray | None = None
) -> np.ndarray:
    """Shade UQ1.12 colours ``(n, 3)`` with SQ1.F normals ``(n, 3)``: UQ1.12 ``(n, 3)``.

    ``illumination`` ``(n,)`` UQ1.12 scales each sample's diffuse and specular terms
    (gradient-magnitude illumination modulation, rounded half up)."""
    if sh.maps is not None:
        i = _cell_index(normals, sh.cfg.map_size)
        diffuse, specular = sh.maps[0][i], sh.maps[1][i]
    else:
        diffuse, specular = _lighting_terms(sh, normals, sh.half)
    if illumination is not None:
        illumination = np.asarray(illumination, dtype=np.int64)
        diffuse = round_shift_raw(diffuse * illumination, 12, 1)
        specular = round_shift_raw(specular * illumination, 12, 1)
    return shade_raw(sh.ka, np.asarray(rgb, dtype=np.int64), diffuse[:, None], specular[:, None])


# The two functions below are the shader's arithmetic, written once for int64 arrays (the
# vectorised API above) and int64 scalars (the functional rung's compiled kernel).


def light_terms_raw(nx, ny, nz, lx, ly, lz, hx, hy, hz, intensity, kd, entries: int, f: int):
    """One light's diffuse factor (UQ4.12) and specular-table index (``entries`` steps) of
    SQ1.``f`` normals ``(nx, ny, nz)`` (int64 arrays or scalars); ``(lx, ly, lz)`` and
    ``(hx, hy, hz)`` are the light and half vectors, SQ1.``f`` (scalars, or the half
    vector's components as ``(n,)`` rows)."""
    ndl = np.maximum(round_shift_raw(nx * lx + ny * ly + nz * lz, 2 * f - 12, 1), 0)
    ndh = round_shift_raw(nx * hx + ny * hy + nz * hz, 2 * f - 12, 1)
    ndh = np.minimum(np.maximum(ndh, 0), ONE)
    diffuse = round_shift_raw(intensity * kd * np.minimum(ndl, ONE), 2 * _COEF, 1)
    return diffuse, round_shift_raw(ndh * entries, 12, 1)


def cell_index_raw(nx, ny, nz, r: int):
    """Cube-map cell of SQ1.F normals (int64 arrays or scalars): the face of the largest
    ``|component|`` (x before y before z on ties) and its sign, then the other two
    components divided by it, cut into ``r`` steps each; the zero normal maps to the last
    entry, ``6 r^2``."""
    ax, ay, az = np.abs(nx), np.abs(ny), np.abs(nz)
    sx = (ax >= ay) * (ax >= az) * 1  # one-hot face axis, as integers
    sy = (1 - sx) * (ay >= az)
    sz = 1 - sx - sy
    major = ax * sx + ay * sy + az * sz
    sign = ((nx * sx + ny * sy + nz * sz) < 0) * 1
    u = ny * sx + nx * (sy + sz)  # the other axes in order: x: (y, z), y: (x, z), z: (x, y)
    w = nz * (sx + sy) + ny * sz
    safe = np.maximum(major, 1)
    iu = np.minimum(np.maximum(((u + safe) * r) // (2 * safe), 0), r - 1)
    iw = np.minimum(np.maximum(((w + safe) * r) // (2 * safe), 0), r - 1)
    idx = (((sy + 2 * sz) * 2 + sign) * r + iu) * r + iw
    zero = (major == 0) * 1
    return idx * (1 - zero) + 6 * r * r * zero


def specular_raw(intensity, ks, spec_value):
    """One light's specular term (UQ4.12) from its table entry ``spec_value``."""
    return round_shift_raw(intensity * ks * spec_value, 2 * _COEF, 1)


def shade_raw(ka, rgb, diffuse, specular):
    """``clamp(ka c + diffuse c + specular, 0, 1)`` in UQ1.12 (int64 arrays or scalars)."""
    lit = round_shift_raw(ka * rgb, _COEF, 1) + round_shift_raw(diffuse * rgb, 12, 1) + specular
    return np.minimum(np.maximum(lit, 0), ONE)
