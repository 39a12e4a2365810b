"""The golden ray walk compiled: whole rays at a time, the same float64 operations.

# Ref: Levoy, IEEE CG&A 1988 (front-to-back compositing, early ray termination);
#      design.md section 4 (the golden renderer is float64 and knows no hardware).

The step engine (:func:`hwsim.golden.steps.run_steps`) walks all rays one global step at a
time in NumPy; it serves every plan kind and feature.  For the common case this module
walks each ray from its first to its last sample in compiled code instead, and stops it
at early termination, as the step engine does: ideal ``ray`` sample positions,
trilinear filtering, post-classified composite front to back, voxel gradients, Phong
with directional lights (parallel or perspective), gradient-magnitude opacity and
illumination modulation.  Every other scene takes the step engine
(:func:`eligible` says which).

Every sample is computed with the step engine's float64 operations in the step engine's
order, without fused multiply-adds (numba does not contract without ``fastmath``): the
position ``o + t d`` with ``t = (k_first + k_dir j) dt``, the seven lerps of
:func:`~hwsim.golden.sampling.trilinear_rows`, ``numpy.interp``'s rule for the transfer
function, :func:`~hwsim.golden.shading.phong`, the opacity correction through the shared
:func:`~hwsim.golden.power.power`; so the image is the step engine's bit for bit (tested
on every supported feature).  Rays are independent, so a frame's rays are dealt to
:func:`hwsim.core.threads.frame_threads` threads tile by tile (square image tiles); the bits do not
depend on the thread count.
"""

from __future__ import annotations

import threading
from concurrent import futures
from typing import TYPE_CHECKING

import numba
import numpy as np

from hwsim.core import interrupt
from hwsim.core.threads import frame_threads, pool
from hwsim.golden.power import power_scalar
from hwsim.golden.shading import unit_vector

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = ["eligible", "walk"]

#: Side in pixels of the image tiles dealt to threads: a tile's rays advance together, so
#: the voxels one step reads are still in cache for the next.
_TILE = 32


def eligible(renderer) -> bool:
    """Whether :func:`walk` renders ``renderer``'s frame (a ``golden.render._Renderer``)."""
    r, scene, plan = renderer, renderer.scene, renderer.plan
    return (
        plan.kind == "ray"
        and r.mode == "composite"
        and r.kind == "trilinear"
        and not plan.back_to_front
        and r.pre is None
        and r.classifier is None
        and r.geometry is None
        and r.reflectance_map is None
        and scene.crop is None
        and not scene.cut_planes
        and scene.cursor is None
        and (not r.need_grad or r.rows is not None)
    )


def walk(
    renderer, progress: Callable[[int, int], None] | None = None
) -> tuple[np.ndarray, int, int]:
    """Composite every ray of ``renderer``'s plan: ``(acc (n_rays, 4), samples, rays)``."""
    plan = renderer.plan
    args = _kernel_args(renderer)
    acc = np.zeros((plan.n_rays, 4))
    taken = np.zeros(plan.ray_ids.size, dtype=np.int64)
    chunks = _tiles(plan.ray_ids, plan.shape[1])
    threads = min(frame_threads(), max(1, len(chunks)))
    if threads == 1:
        for k, sel in enumerate(chunks):
            _walk(sel, *args, acc, taken)
            if progress is not None:
                progress(plan.n_steps * (k + 1) // len(chunks), plan.n_steps)
    else:
        _walk_threaded(chunks, threads, args, acc, taken, plan.n_steps, progress)
    return acc, int(taken.sum()), int(np.count_nonzero(taken))


def _walk_threaded(chunks, threads, args, acc, taken, n_steps, progress) -> None:
    """``_walk`` over ``chunks`` on ``threads`` threads: each takes the next tile as it
    finishes one (tiles differ in cost)."""
    tiles = iter(chunks)
    lock = threading.Lock()
    done = [0]

    def work() -> None:
        while True:
            interrupt.check()  # Ctrl-C: stop between tiles
            with lock:
                sel = next(tiles, None)
            if sel is None:
                return
            _walk(sel, *args, acc, taken)
            with lock:
                done[0] += 1

    jobs = [pool(threads).submit(work) for _ in range(threads)]
    while futures.wait(jobs, timeout=0.2).not_done:
        if progress is not None:
            progress(n_steps * done[0] // len(chunks), n_steps)
    for job in jobs:
        job.result()
    if progress is not None:
        progress(n_steps, n_steps)


def _lights(renderer) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lights' directions, intensities and (a parallel view's) half vectors."""
    r, plan = renderer, renderer.plan
    if not r.scene.lit:
        return np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))
    directions = np.array([d for d, _ in r.lights], dtype=np.float64).reshape(-1, 3)
    intensities = np.array([i for _, i in r.lights], dtype=np.float64)
    # The half vectors of a parallel view, as phong makes them (one per light).
    halves = np.zeros_like(directions)
    if plan._view.ndim != 2:
        for k, direction in enumerate(directions):
            halves[k] = unit_vector(plan._view + direction)
    return directions, intensities, halves


def _kernel_args(renderer) -> tuple:
    """``_walk``'s arguments after the tile's rays and before the outputs."""
    r, plan, tf = renderer, renderer.plan, renderer.transfer
    material = r.scene.material
    per_ray_view = plan._view.ndim == 2
    directions, intensities, halves = _lights(renderer)
    empty = np.zeros((0, 2))
    gp = tf.gradient_points if tf.gradient_points is not None else empty
    ip = tf.illumination_points if tf.illumination_points is not None else empty
    field = r.rows if r.rows is not None else r.flat.reshape(-1, 1)
    d = plan._d.reshape(-1, 3)
    view = plan._view.reshape(-1, 3)
    dt = float(plan._dt)
    return (
        np.ascontiguousarray(plan._o),
        np.ascontiguousarray(d),
        float(plan.k_first),
        float(plan.k_dir),
        dt,
        plan.j_lo,
        plan.j_hi,
        plan.ray_ids,
        field,
        np.asarray(r.volume.shape, dtype=np.int64),
        tf.values,
        np.ascontiguousarray(tf.rgba.T),
        np.ascontiguousarray(gp[:, 0]),
        np.ascontiguousarray(gp[:, 1:].T),
        np.ascontiguousarray(ip[:, 0]),
        np.ascontiguousarray(ip[:, 1:].T),
        directions,
        intensities,
        halves,
        np.ascontiguousarray(view),
        np.array(
            [material.ambient, material.diffuse, material.specular, material.shininess],
            dtype=np.float64,
        ),
        np.array(
            [r.need_grad, r.scene.lit, tf.modulates, tf.modulates_illumination, per_ray_view],
            dtype=np.bool_,
        ),
        dt / r.ref,
        float(r.scene.render.early_termination),
    )


def _tiles(ray_ids: np.ndarray, width: int) -> list[np.ndarray]:
    """Plan-ray indices grouped by square image tiles of :data:`_TILE` pixels a side."""
    row, col = ray_ids // width, ray_ids % width
    tile = (row // _TILE) * ((width + _TILE - 1) // _TILE) + col // _TILE
    order = np.argsort(tile, kind="stable")
    bounds = np.flatnonzero(np.diff(tile[order])) + 1
    return np.split(order, bounds) if order.size else []


@numba.njit(cache=True, nogil=True)
def _interp(x, xp, fp, row):  # pragma: no cover - compiled
    """``numpy.interp(x, xp, fp[row])`` for one ``x``, by NumPy's rule (binary search for
    the last ``xp[j] <= x``; end values outside; ``fp[j]`` exactly on a control point).
    ``fp`` is 2-D and indexed in place: a row view per call would cost reference counts."""
    n = xp.shape[0]
    if n == 1:
        return fp[row, 0]
    if x > xp[n - 1]:
        return fp[row, n - 1]
    if x < xp[0]:
        return fp[row, 0]
    lo, hi = 0, n
    while lo < hi:
        mid = lo + ((hi - lo) >> 1)
        if x >= xp[mid]:
            lo = mid + 1
        else:
            hi = mid
    j = lo - 1
    if j == n - 1 or xp[j] == x:
        return fp[row, j]
    slope = (fp[row, j + 1] - fp[row, j]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + fp[row, j]
    if np.isnan(out):
        out = slope * (x - xp[j + 1]) + fp[row, j + 1]
        if np.isnan(out) and fp[row, j] == fp[row, j + 1]:
            out = fp[row, j]
    return out


# ``_walk``'s parts are inlined into it at Numba IR level (``inline="always"``): named steps
# of one compiled loop, as fast as the loop written out in one body (its LLVM code calls
# none of them and counts no references inside the loop).  An array a part takes and last
# uses inside a branch would be reference counted (an atomic add) on every sample: see
# hwsim.memory.sdram_kernel, where that cost about 10%.


@numba.njit(inline="always", nogil=True)
def _grid(shape):  # pragma: no cover - compiled
    """``shape``'s last index per axis (float), last cell origin per axis (int), and
    ``(ny, nx, sz, sy, sx)``: the row lengths and the tap strides in ``field`` rows (0
    along an axis one voxel thick, so its taps read the same voxel)."""
    nz, ny, nx = shape[0], shape[1], shape[2]
    top = (np.float64(nz - 1), np.float64(ny - 1), np.float64(nx - 1))
    cap = (max(nz - 2, 0), max(ny - 2, 0), max(nx - 2, 0))
    layout = (ny, nx, ny * nx if nz > 1 else 0, nx if ny > 1 else 0, 1 if nx > 1 else 0)
    return top, cap, layout


@numba.njit(inline="always", nogil=True)
def _step_span(sel, j_lo, j_hi):  # pragma: no cover - compiled
    """The first and last step any of the rays ``sel`` samples."""
    j_first, j_last = j_lo[sel[0]], j_hi[sel[0]]
    for r in sel:
        j_first, j_last = min(j_first, j_lo[r]), max(j_last, j_hi[r])
    return j_first, j_last


@numba.njit(inline="always", nogil=True)
def _sample(field, o, d, r, dr, t, top, cap, layout, s):  # pragma: no cover - compiled
    """Every component of ``field`` at ray ``r``'s point ``o[r] + t d[dr]`` (clamped into
    the volume) into ``s``, by the seven lerps of ``trilinear_rows`` in its order."""
    ny, nx, sz, sy, sx = layout
    p0 = min(max(o[r, 0] + t * d[dr, 0], 0.0), top[0])
    p1 = min(max(o[r, 1] + t * d[dr, 1], 0.0), top[1])
    p2 = min(max(o[r, 2] + t * d[dr, 2], 0.0), top[2])
    i0 = min(np.int64(np.floor(p0)), cap[0])
    i1 = min(np.int64(np.floor(p1)), cap[1])
    i2 = min(np.int64(np.floor(p2)), cap[2])
    fz, fy, fx = p0 - i0, p1 - i1, p2 - i2
    base = (i0 * ny + i1) * nx + i2
    for c in range(field.shape[1]):
        y0 = field[base, c] + fx * (field[base + sx, c] - field[base, c])
        y1 = field[base + sy, c] + fx * (field[base + sy + sx, c] - field[base + sy, c])
        near = y0 + fy * (y1 - y0)
        b2 = base + sz
        y0 = field[b2, c] + fx * (field[b2 + sx, c] - field[b2, c])
        y1 = field[b2 + sy, c] + fx * (field[b2 + sy + sx, c] - field[b2 + sy, c])
        far = y0 + fy * (y1 - y0)
        s[c] = near + fz * (far - near)


@numba.njit(inline="always", nogil=True)
def _half_vector(view, vr, l0, l1, l2, h):  # pragma: no cover - compiled
    """Into ``h``: the unit half vector of view ``view[vr]`` and light ``(l0, l1, l2)``
    (zero where the sum vanishes), as phong makes it for a perspective ray."""
    h0 = view[vr, 0] + l0
    h1 = view[vr, 1] + l1
    h2 = view[vr, 2] + l2
    norm = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
    if norm > 1e-12:
        h[0], h[1], h[2] = h0 / norm, h1 / norm, h2 / norm
    else:
        h[0], h[1], h[2] = 0.0, 0.0, 0.0


@numba.njit(inline="always", nogil=True)
def _phong(s, mag, illum, rgb, lit_args, vr, out, h):  # pragma: no cover - compiled
    """Phong-shade ``rgb`` in place at the gradient ``s[1:4]`` (magnitude ``mag``), each
    light's term scaled by ``illum`` when illumination is modulated; ``lit_args`` is
    ``(lights, intensities, halves, view, material, mod_illum, per_ray_view)`` and ``vr``
    the ray's row of ``view``; ``out`` and ``h`` are scratch."""
    lights, intensities, halves, view, material, mod_illum, per_ray_view = lit_args
    ka, kd, ks, shininess = material[0], material[1], material[2], material[3]
    scale = -1.0 / mag if mag > 1e-12 else 0.0
    n0, n1, n2 = s[1] * scale, s[2] * scale, s[3] * scale
    for c in range(3):
        out[c] = ka * rgb[c]
    for k in range(lights.shape[0]):
        l0, l1, l2 = lights[k, 0], lights[k, 1], lights[k, 2]
        ndl = max(n0 * l0 + n1 * l1 + n2 * l2, 0.0)
        if per_ray_view:
            _half_vector(view, vr, l0, l1, l2, h)
        else:
            h[0], h[1], h[2] = halves[k, 0], halves[k, 1], halves[k, 2]
        ndh = n0 * h[0] + n1 * h[1] + n2 * h[2]
        spec = ks * power_scalar(max(ndh, 0.0), shininess)
        for c in range(3):
            light = intensities[k] * (kd * ndl * rgb[c] + spec)
            out[c] += illum * light if mod_illum else light
    for c in range(3):
        rgb[c] = min(max(out[c], 0.0), 1.0)


@numba.njit(inline="always", nogil=True)
def _composite(acc, ray, rgb, a, expo, ert):  # pragma: no cover - compiled
    """Composite colour ``rgb``, opacity ``a`` (corrected by the exponent ``expo``) behind
    ``acc[ray]``, front to back; whether the ray has reached early termination ``ert``."""
    A = acc[ray, 3]
    a = 1.0 - power_scalar(1.0 - a, expo)
    weight = (1.0 - A) * a
    for c in range(3):
        acc[ray, c] += weight * rgb[c]
    A += weight
    acc[ray, 3] = A
    return ert < 1.0 and not A < ert


@numba.njit(cache=True, nogil=True)
def _walk(
    sel,
    o,
    d,
    k_first,
    k_dir,
    dt,
    j_lo,
    j_hi,
    ray_ids,
    field,
    shape,
    tf_x,
    tf_rgba,
    gp_x,
    gp_f,
    ip_x,
    ip_f,
    lights,
    intensities,
    halves,
    view,
    material,
    flags,
    expo,
    ert,
    acc,
    taken,
):  # pragma: no cover - compiled
    need_grad, lit, modulates = flags[0], flags[1], flags[2]
    mod_illum, per_ray_view = flags[3], flags[4]
    lit_args = (lights, intensities, halves, view, material, mod_illum, per_ray_view)
    top, cap, layout = _grid(shape)
    s, rgb, out, h = np.empty(4), np.empty(3), np.empty(3), np.empty(3)
    shared_d = d.shape[0] == 1
    # The chunk's rays advance together, one step at a time: neighbouring rays sample
    # neighbouring voxels, which stay in cache.  Each ray's samples keep their order.
    j_first, j_last = _step_span(sel, j_lo, j_hi)
    done = np.zeros(sel.shape[0], dtype=np.bool_)
    for j in range(j_first, j_last + 1):
        t = (k_first + k_dir * j) * dt
        for q in range(sel.shape[0]):
            r = sel[q]
            if done[q] or j < j_lo[r] or j > j_hi[r]:
                continue
            _sample(field, o, d, r, 0 if shared_d else r, t, top, cap, layout, s)
            taken[r] += 1
            v = s[0]
            a = _interp(v, tf_x, tf_rgba, 3)
            if not a > 0:
                continue
            for c in range(3):
                rgb[c] = _interp(v, tf_x, tf_rgba, c)
            if need_grad:
                gx, gy, gz = s[1], s[2], s[3]
                mag = np.sqrt(gx * gx + gy * gy + gz * gz)
                if modulates:
                    a = a * _interp(mag, gp_x, gp_f, 0)
                if lit:
                    illum = _interp(mag, ip_x, ip_f, 0) if mod_illum else 1.0
                    _phong(s, mag, illum, rgb, lit_args, r if per_ray_view else 0, out, h)
            if _composite(acc, ray_ids[r], rgb, a, expo, ert):
                done[q] = True
