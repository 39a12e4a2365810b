"""Embedded opaque geometry: host-side rasterisation into a colour image and a depth
buffer, the per-sample depth, the depth test and the blend behind the volume (float64).

# Ref: architectures.md section 4 (VolumePro 1000 embeds opaque polygons through image +
#      24-bit depth buffers with per-buffer depth tests <, <=, =, >=, >, !=; vli.h).

Depth metric (shared by golden and the fixed-point rungs): the ray parameter ``t``
(parallel: signed distance along the view direction from the plane through the volume
centre; perspective: distance from the eye), normalised linearly over the volume's
bounding sphere::

    depth = clip((t - t_near) / (t_far - t_near), 0, 1)
    parallel:     t_near = -R,       t_far = +R
    perspective:  t_near = (D - 1) R, t_far = (D + 1) R      (D = view.distance)

so every sample inside the volume has a depth in ``[0, 1]`` and a cleared buffer (no
geometry) holds 1.0 (far).  A sample is kept when ``sample_depth <test> pixel_depth``;
after the ray, the pixel's geometry colour ``c`` (coverage ``a``: 1 where a primitive
was hit) is composited *behind* the accumulated volume: ``C += (1 - A) a c``,
``A += (1 - A) a``.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.paths import input_file
from hwsim.golden.camera import Camera, index_to_world
from hwsim.spec.scene_features import GeometrySpec
from hwsim.volumes.volume import Volume

__all__ = [
    "GeometryBuffers",
    "depth_range",
    "rasterise",
    "sample_depth",
    "depth_pass",
    "blend_behind",
    "TEST_OPERATORS",
    "STOPPING_TESTS",
]

#: Depth tests after whose first failure every later sample of a ray fails too (sample
#: depth grows along the ray, front to back): the ray ends there.
STOPPING_TESTS = ("<", "<=")
TEST_OPERATORS = {
    "<": operator.lt,
    "<=": operator.le,
    "==": operator.eq,
    ">=": operator.ge,
    ">": operator.gt,
    "!=": operator.ne,
}


@dataclass(frozen=True)
class GeometryBuffers:
    """Per image pixel (row-major ``H * W``): ``rgba (n, 4)`` colour and coverage in
    ``[0, 1]`` and ``depth (n,)`` normalised (1.0 = far / no geometry)."""

    rgba: np.ndarray
    depth: np.ndarray


def depth_range(camera: Camera, distance: float) -> tuple[float, float]:
    """``(t_near, t_far)`` of the volume's bounding sphere along the rays."""
    r = camera.radius
    if camera.perspective:
        return (distance - 1.0) * r, (distance + 1.0) * r
    return -r, r


def _normalise(t: np.ndarray, near: float, far: float) -> np.ndarray:
    return np.clip((t - near) / (far - near), 0.0, 1.0)


def _sphere_hits(o: np.ndarray, d: np.ndarray, center, radius: float, perspective: bool):
    oc = o - np.asarray(center, dtype=np.float64)
    b = np.sum(oc * d, axis=1) if d.ndim == 2 else oc @ d
    c = np.sum(oc * oc, axis=1) - radius * radius
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    t0, t1 = -b - root, -b + root
    t = np.where(perspective & (t0 < 0), t1, t0)
    ok = (disc >= 0) & ((t >= 0) if perspective else True)
    return np.where(ok, t, np.inf)


def _box_hits(o: np.ndarray, d: np.ndarray, lo, hi, perspective: bool):
    d = np.broadcast_to(d, o.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (np.asarray(lo) - o) / d
        t2 = (np.asarray(hi) - o) / d
    flat = d == 0
    inside = (o >= np.asarray(lo)) & (o <= np.asarray(hi))
    near = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)).max(axis=1)
    far = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)).min(axis=1)
    t = np.maximum(near, 0.0) if perspective else near
    ok = (near <= far) & (far >= 0 if perspective else True)
    return np.where(ok, t, np.inf)


def rasterise(
    spec: GeometrySpec, camera: Camera, distance: float, base_dir: Path | None = None
) -> GeometryBuffers:
    """Colour and depth buffers of ``spec`` for ``camera``'s pixels (host side, float64):
    the nearest primitive per pixel (flat colour), or the user's ``.npy`` pair."""
    n = camera.width * camera.height
    near, far = depth_range(camera, distance)
    if spec.color is not None:
        return _load_pair(spec, camera, base_dir or Path.cwd())
    o, d = camera.origins, camera.directions
    best = np.full(n, np.inf)
    rgb = np.zeros((n, 3))
    prims = [
        (s.color, _sphere_hits(o, d, s.center, s.radius, camera.perspective)) for s in spec.spheres
    ]
    prims += [(b.color, _box_hits(o, d, b.lo, b.hi, camera.perspective)) for b in spec.boxes]
    for color, t in prims:
        closer = t < best
        best = np.where(closer, t, best)
        rgb[closer] = color
    hit = np.isfinite(best)
    depth = np.ones(n)
    depth[hit] = _normalise(best[hit], near, far)
    rgba = np.zeros((n, 4))
    rgba[hit, :3] = rgb[hit]
    rgba[hit, 3] = 1.0
    return GeometryBuffers(rgba, depth)


def _load_pair(spec: GeometrySpec, camera: Camera, base_dir: Path) -> GeometryBuffers:
    h, w = camera.height, camera.width
    arrays = {}
    for key, path, shapes in (
        ("geometry.color", spec.color, ((h, w, 3), (h, w, 4))),
        ("geometry.depth", spec.depth, ((h, w),)),
    ):
        p = Path(path)  # type: ignore[arg-type]
        p = input_file(p if p.is_absolute() else base_dir / p, key)  # never a FIFO
        try:
            a = np.load(p, allow_pickle=False).astype(np.float64)
        except (OSError, ValueError) as exc:
            raise InputError(f"not a readable .npy file: {exc}", source=str(p), key=key) from None
        if a.shape not in shapes:
            allowed = " or ".join(str(s) for s in shapes)
            raise InputError(
                f"shape {a.shape} does not match the image", source=str(p), key=key, allowed=allowed
            )
        if not (np.isfinite(a).all() and a.min() >= 0 and a.max() <= 1):
            raise InputError(
                "values must be finite and in 0 .. 1", source=str(p), key=key, allowed="0 .. 1"
            )
        arrays[key] = a
    depth = arrays["geometry.depth"].ravel()
    color = arrays["geometry.color"].reshape(h * w, -1)
    rgba = np.zeros((h * w, 4))
    rgba[:, :3] = color[:, :3]
    rgba[:, 3] = color[:, 3] if color.shape[1] == 4 else (depth < 1.0)
    return GeometryBuffers(rgba, depth)


def sample_depth(zyx: np.ndarray, camera: Camera, volume: Volume, distance: float) -> np.ndarray:
    """Normalised depth ``(n,)`` of samples at index positions ``zyx (n, 3)``."""
    p = index_to_world(zyx, volume)
    if camera.perspective:
        eye = camera.origins[0]
        t = np.sqrt(np.sum((p - eye) ** 2, axis=1))
    else:
        t = p @ camera.d
    return _normalise(t, *depth_range(camera, distance))


def depth_pass(test: str, sample: np.ndarray, pixel: np.ndarray) -> np.ndarray:
    """Boolean mask of samples whose depth passes ``sample <test> pixel``."""
    return TEST_OPERATORS[test](sample, pixel)


def blend_behind(acc: np.ndarray, rgba: np.ndarray) -> None:
    """Composite the geometry behind float accumulators ``acc (n, 4)`` (premultiplied),
    in place."""
    w = (1.0 - acc[:, 3]) * rgba[:, 3]
    acc[:, :3] += w[:, None] * rgba[:, :3]
    acc[:, 3] += w
