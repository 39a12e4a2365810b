"""Phong shading (Blinn half-vector), cropping and cut-plane masks, in float64.

# Ref: Phong, CACM 1975; Blinn, SIGGRAPH 1977; VolumePro 500 crop and cut plane
#      (architectures.md section 3).

The surface normal is ``N = -g / |g|`` (gradients point toward denser material, normals
out of it).  A zero gradient gives ``N = 0``: ambient light only, never NaN.  Colour is
``clip(ka c + sum_l I_l (kd max(N.L, 0) c + ks max(N.H, 0)^n), 0, 1)`` with
``H = normalize(L + V)`` and white specular light.

Reflectance maps (VolumePro 500) are the same model at fewer normals: each normal is
replaced by the centre of its cell in a cube map of ``size x size`` cells per face (the
face of its largest component; the other two, divided by it, cut into ``size`` equal
steps), and Phong is evaluated there.  Golden at that machine's positions shades so, so
its error against the fixed-point maps is numerical only.
"""

from __future__ import annotations

import numpy as np

from hwsim.golden.power import power
from hwsim.spec.scene import CropSpec, CutPlane, Material

__all__ = [
    "magnitude",
    "normals",
    "cube_face",
    "cube_map_normals",
    "phong",
    "unit_vector",
    "crop_keep",
    "cut_factor",
]

_TINY = 1e-12


def magnitude(g: np.ndarray) -> np.ndarray:
    """``|g|`` of vectors ``(n, 3)``: ``(n,)`` float64."""
    return np.sqrt(g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + g[:, 2] * g[:, 2])


def normals(g: np.ndarray) -> np.ndarray:
    """Unit normals ``-g/|g|`` of gradients ``(n, 3)``; zero where ``|g|`` is zero."""
    mag = magnitude(g)
    scale = np.divide(-1.0, mag, out=np.zeros_like(mag), where=mag > _TINY)
    return g * scale[:, None]


def cube_face(n: np.ndarray):
    """The cube-map face of each normal ``(n, 3)``: ``(a, axis, rows, major, others)`` --
    ``|n|`` per component, the major axis (the face), the row indices, ``|n|`` on the
    major axis and the two other axes (the face's coordinates) of each row."""
    a = np.abs(n)
    axis = np.argmax(a, axis=1)
    rows = np.arange(n.shape[0])
    major = a[rows, axis]
    others = np.array([[1, 2], [0, 2], [0, 1]])[axis]
    return a, axis, rows, major, others


def cube_map_normals(n: np.ndarray, size: int) -> np.ndarray:
    """Unit normals ``(n, 3)`` moved to the centre of their cube-map cell (``size`` cells
    per face edge); zero normals stay zero."""
    _, axis, rows, major, others = cube_face(n)
    out = np.zeros_like(n)
    out[rows, axis] = np.sign(n[rows, axis])
    safe = np.where(major > _TINY, major, 1.0)
    for k in (0, 1):
        u = n[rows, others[:, k]] / safe  # in [-1, 1] on the face
        cell = np.clip(np.floor((u + 1.0) * 0.5 * size), 0, size - 1)
        out[rows, others[:, k]] = (cell + 0.5) / size * 2.0 - 1.0
    out = unit_vector(out)
    out[major <= _TINY] = 0.0
    return out


def unit_vector(v: np.ndarray) -> np.ndarray:
    """Rows (or one vector) scaled to unit length; zero vectors stay zero."""
    if v.ndim == 1:
        norm = float(np.linalg.norm(v))
        return v / norm if norm > _TINY else np.zeros(3)
    norm = magnitude(v)[:, None]
    return np.divide(v, norm, out=np.zeros_like(v), where=norm > _TINY)


def phong(
    rgb: np.ndarray,
    g: np.ndarray,
    lights: list[tuple[np.ndarray, float]],
    toward_viewer: np.ndarray,
    material: Material,
    reflectance_map: int | None = None,
    modulation: np.ndarray | None = None,
) -> np.ndarray:
    """Shade colours ``rgb (n, 3)`` with gradients ``g (n, 3)`` (world xyz).

    ``lights`` are (unit direction toward the light, intensity) pairs in world space;
    ``toward_viewer`` is ``(3,)`` (parallel: one half vector per light) or ``(n, 3)``
    unit vectors; ``reflectance_map`` (cells per cube-map face edge) shades at the cell
    centres (:func:`cube_map_normals`); ``modulation`` ``(n,)`` scales each sample's
    diffuse and specular light (gradient-magnitude illumination modulation).  Returns
    float64 ``(n, 3)`` clipped to ``[0, 1]``.
    """
    n = normals(g)
    if reflectance_map is not None:
        n = cube_map_normals(n, reflectance_map)
    out = material.ambient * rgb
    for direction, intensity in lights:
        # Dot products written out (not BLAS, whose fused multiply-adds depend on the
        # CPU): the compiled ray walk computes the same bits.
        ndl = np.maximum(_dot(n, direction), 0.0)
        ndh = _dot(n, unit_vector(toward_viewer + direction))
        spec = material.specular * power(np.maximum(ndh, 0.0), material.shininess)
        light = intensity * (material.diffuse * ndl[:, None] * rgb + spec[:, None])
        out += light if modulation is None else modulation[:, None] * light
    return np.clip(out, 0.0, 1.0, out=out)


def _dot(n: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise ``n . v`` of ``(n, 3)`` rows with one vector ``(3,)`` or rows ``(n, 3)``."""
    v = np.broadcast_to(v, n.shape)
    return n[:, 0] * v[:, 0] + n[:, 1] * v[:, 1] + n[:, 2] * v[:, 2]


def crop_keep(zyx: np.ndarray, crop: CropSpec) -> np.ndarray:
    """Boolean mask of samples the crop keeps (index coordinates, inclusive slabs;
    ``crop.mode`` says in how many of the three a kept sample lies)."""
    slabs = np.zeros(zyx.shape[0], dtype=np.int64)
    for axis, limits in (("z", crop.z), ("y", crop.y), ("x", crop.x)):
        if limits is None:
            slabs += 1
        else:
            col = "zyx".index(axis)
            slabs += (zyx[:, col] >= limits[0]) & (zyx[:, col] <= limits[1])
    inside = slabs >= crop.slabs_needed
    return ~inside if crop.invert else inside


def cut_factor(p_world: np.ndarray, planes: tuple[CutPlane, ...]) -> np.ndarray:
    """Opacity factor in ``[0, 1]`` of thick cut planes at world points ``(n, 3)`` xyz."""
    factor = np.ones(p_world.shape[0])
    for plane in planes:
        normal = np.asarray(plane.normal, dtype=np.float64)
        normal /= np.linalg.norm(normal)
        beyond = np.abs(p_world @ normal - plane.offset) - plane.thickness / 2.0
        if plane.falloff > 0:
            f = np.clip(1.0 - beyond / plane.falloff, 0.0, 1.0)
        else:
            f = (beyond <= 0).astype(np.float64)
        factor *= 1.0 - f if plane.invert else f
    return factor
