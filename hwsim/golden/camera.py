"""Camera geometry: view vectors, rays through pixel centres, world <-> index space.

# Ref: design.md section 9 (the AZ,EL convention); docs/numerics.md (conventions).

Conventions (also in docs/numerics.md):

* Index space is ``(z, y, x)``; voxel centres sit at integer coordinates and the volume's
  box is ``[-0.5, n - 0.5]`` on each axis.
* World space is ``(x, y, z)``; voxel ``i`` lies at ``(i - (n - 1) / 2) * spacing``, so
  the volume is centred on the origin.
* The view direction is ``d = (sin az cos el, sin el, cos az cos el)``; up is
  ``u = dd/d(el)``; right is ``r = d x u``.  Image row 0 is the top (+u), column 0 the
  left (-r).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from hwsim.spec.scene import ViewSpec
from hwsim.volumes.volume import Volume

__all__ = ["Camera", "view_vectors", "world_to_index", "index_to_world"]


def view_vectors(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit view direction ``d``, up ``u`` and right ``r`` in world ``(x, y, z)``."""
    az, el = np.radians(azimuth), np.radians(elevation)
    d = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    u = np.array([-np.sin(az) * np.sin(el), np.cos(el), -np.cos(az) * np.sin(el)])
    return d, u, np.cross(d, u)


def world_to_index(p_xyz: np.ndarray, volume: Volume) -> np.ndarray:
    """World points ``(..., 3)`` in ``(x, y, z)`` to index coordinates ``(..., 3)`` in
    ``(z, y, x)``."""
    shape = np.asarray(volume.shape, dtype=np.float64)
    spacing = np.asarray(volume.spacing, dtype=np.float64)
    if p_xyz.ndim == 2 and p_xyz.shape[1] == 3 and p_xyz.dtype == np.float64:
        out = np.empty(p_xyz.shape)  # one compiled pass, the same bits
        _world_to_index_rows(p_xyz, spacing, (shape - 1.0) / 2.0, out)
        return out
    return p_xyz[..., ::-1] / spacing + (shape - 1.0) / 2.0


@numba.njit(cache=True, nogil=True)
def _world_to_index_rows(p_xyz, spacing, centre, out):  # pragma: no cover - compiled
    """:func:`world_to_index` of ``(n, 3)`` points one at a time: ``p / spacing +
    centre`` axis by axis, the array expression's operations, so the same bits."""
    for i in range(p_xyz.shape[0]):
        for c in range(3):
            out[i, c] = p_xyz[i, 2 - c] / spacing[c] + centre[c]


@numba.njit(cache=True, nogil=True)
def _parallel_origins(px, py, s, r, u, out):  # pragma: no cover - compiled
    """Parallel-view ray origins, pixel by pixel in row-major order: ``(x s) r + (y s)
    u`` with ``x = px[col]``, ``y = py[row]`` (the meshgrid expression's operations in
    its order, no fused multiply-adds), so the same bits without the temporaries."""
    w = px.shape[0]
    for row in range(py.shape[0]):
        ys = py[row] * s
        for col in range(w):
            xs = px[col] * s
            for c in range(3):
                out[row * w + col, c] = xs * r[c] + ys * u[c]


def index_to_world(i_zyx: np.ndarray, volume: Volume) -> np.ndarray:
    """Index coordinates ``(..., 3)`` in ``(z, y, x)`` to world points in ``(x, y, z)``."""
    shape = np.asarray(volume.shape, dtype=np.float64)
    spacing = np.asarray(volume.spacing)
    return ((i_zyx - (shape - 1.0) / 2.0) * spacing)[..., ::-1]


@dataclass(frozen=True)
class Camera:
    """Rays of one view.

    ``origins`` are world points, one per pixel (row-major, ``H * W``); ``directions`` are
    unit world vectors, one per pixel for perspective, a single ``(3,)`` for parallel.
    For parallel projection the origins lie on the plane through the volume centre
    perpendicular to ``d`` (ray parameter ``t = 0`` there); for perspective every origin
    is the eye and ``t`` is the distance from it.
    """

    d: np.ndarray
    u: np.ndarray
    r: np.ndarray
    width: int
    height: int
    perspective: bool
    origins: np.ndarray
    directions: np.ndarray
    radius: float

    @classmethod
    def from_view(cls, view: ViewSpec, volume: Volume) -> Camera:
        d, u, r = view_vectors(view.azimuth, view.elevation)
        radius = 0.5 * float(np.linalg.norm(volume.extent))
        w, h = view.width, view.height
        # Pixel-centre offsets in units of one pixel, x to the right, y up.
        px = (np.arange(w) + 0.5) - w / 2.0
        py = h / 2.0 - (np.arange(h) + 0.5)
        if view.projection == "parallel":
            s = 2.0 * radius / (view.zoom * min(w, h))
            origins = np.empty((w * h, 3))  # (gx s) r + (gy s) u over the pixel grid
            _parallel_origins(px, py, float(s), r, u, origins)
            return cls(d, u, r, w, h, False, origins, d.copy(), radius)
        gx, gy = np.meshgrid(px, py)  # (H, W)
        gx, gy = gx.ravel(), gy.ravel()
        eye = -view.distance * radius * d
        half = np.tan(np.radians(view.fov) / 2.0) / view.zoom
        s = 2.0 * half / h  # image plane at distance 1 from the eye
        dirs = d + (gx * s)[:, None] * r + (gy * s)[:, None] * u
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        origins = np.broadcast_to(eye, dirs.shape)
        return cls(d, u, r, w, h, True, origins, dirs, radius)

    @property
    def toward_viewer(self) -> np.ndarray:
        """Unit vectors from a sample toward the viewer: ``-directions``."""
        return -self.directions

    def light_to_world(self, direction: tuple[float, float, float], space: str) -> np.ndarray:
        """A light direction (toward the light) as a unit world vector."""
        v = np.asarray(direction, dtype=np.float64)
        if space == "view":  # x right, y up, z toward the viewer
            v = v[0] * self.r + v[1] * self.u - v[2] * self.d
        return v / np.linalg.norm(v)
