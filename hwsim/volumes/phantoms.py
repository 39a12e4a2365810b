"""Built-in phantoms: an antialiased ball, the Marschner-Lobb test signal and a CT-like head.

All are float math evaluated at voxel centres (integer indices, axis order ``(z, y, x)``),
deterministic, with a seeded generator for any noise.  ``parse_phantom_spec`` reads the
``NAME[:key=value,...]`` form the CLI and sweeps use.

# Ref: S. R. Marschner and R. J. Lobb, "An evaluation of reconstruction filters for
#      volume rendering", Proc. IEEE Visualization 1994, pp. 100-107 (eq. 1-2).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.budget import require_fits
from hwsim.core.errors import InputError
from hwsim.volumes.volume import Volume

__all__ = [
    "PHANTOMS",
    "PhantomInfo",
    "Param",
    "make_phantom",
    "parse_phantom_spec",
    "marschner_lobb",
    "ML_FM",
    "ML_ALPHA",
]

ML_FM = 6.0  #: Marschner-Lobb modulation frequency f_M
ML_ALPHA = 0.25  #: Marschner-Lobb weight alpha
_HEAD_SLAB = 32  # z slices per slab of the head's layer evaluation
BALL_SUBSAMPLES = 8  #: sub-rows per voxel along y and along z for the ball's coverage
_DTYPES = ("uint8", "int8", "uint16", "int16", "float32", "float64")


@dataclass(frozen=True)
class Param:
    """One phantom parameter: its type, default and allowed range (or choices)."""

    kind: type
    default: Any
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    help: str = ""

    @property
    def allowed(self) -> str:
        if self.choices:
            return ", ".join(self.choices)
        if self.kind is int:
            return f"{int(self.lo)} .. {int(self.hi)}"
        return f"{self.lo:g} .. {self.hi:g}"

    def check(self, value: Any, source: str, key: str) -> Any:
        """``value`` converted to this parameter's type, or :class:`InputError`."""
        try:
            if self.kind is int:
                as_float = float(value)
                if isinstance(value, bool) or not as_float.is_integer():
                    raise ValueError
                value = int(as_float)
            elif self.kind is float:
                if isinstance(value, bool):
                    raise ValueError
                value = float(value)
            else:
                value = str(value)
        except (TypeError, ValueError):
            raise InputError(
                f"must be {self.kind.__name__}, got {value!r}",
                source=source,
                key=key,
                allowed=self.allowed,
            ) from None
        bad = (value not in self.choices) if self.choices else not (self.lo <= value <= self.hi)
        if bad:
            raise InputError(
                f"{value!r} is out of range", source=source, key=key, allowed=self.allowed
            )
        return value


@dataclass(frozen=True)
class PhantomInfo:
    """What ``hwsim phantoms`` lists: a description and the parameters."""

    description: str
    params: dict[str, Param] = field(default_factory=dict)
    build: Callable[..., Volume] | None = None

    @property
    def defaults(self) -> dict[str, Any]:
        return {k: p.default for k, p in self.params.items()}

    def __str__(self) -> str:
        args = ", ".join(f"{k}={p.default} ({p.allowed})" for k, p in self.params.items())
        return f"{self.description}; params: {args}"


# ------------------------------------------------------------------------ analytic


def marschner_lobb(x: Any, y: Any, z: Any, fm: float = ML_FM, alpha: float = ML_ALPHA) -> Any:
    """The Marschner-Lobb signal rho(x, y, z) on ``[-1, 1]^3`` (vectorised, float64).

    ``rho = [(1 - sin(pi z / 2)) + alpha (1 + rho_r(sqrt(x^2 + y^2)))] / (2 (1 + alpha))``
    with ``rho_r(r) = cos(2 pi fm cos(pi r / 2))``.  Values lie in ``[0, 1]``;
    ``rho(0, 0, -1) = 1``, ``rho(0, 0, 1) = 0.2``, ``rho(0, 0, 0) = 0.6``.
    """
    x, y, z = (np.asarray(v, dtype=np.float64) for v in (x, y, z))
    r = np.sqrt(x * x + y * y)
    rho_r = np.cos(2.0 * np.pi * fm * np.cos(np.pi * r / 2.0))
    return ((1.0 - np.sin(np.pi * z / 2.0)) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha))


# ------------------------------------------------------------------------ builders


def _union(parts: list[np.ndarray]) -> np.ndarray:
    return functools.reduce(np.minimum, parts)


def _intersect(parts: list[np.ndarray]) -> np.ndarray:
    return functools.reduce(np.maximum, parts)


def _ball(source: str, size: int, radius: float, value: float, dtype: str) -> Volume:
    dt = np.dtype(dtype)
    if dt.kind in "iu":
        info = np.iinfo(dt)
        if not info.min <= value <= info.max:
            raise InputError(
                f"{value:g} does not fit {dtype}",
                source=source,
                key="value",
                allowed=f"{info.min} .. {info.max}",
            )
    n = size
    centre = (n - 1) / 2.0
    r = radius * n / 2.0
    k = BALL_SUBSAMPLES
    sub = (np.arange(k) + 0.5) / k - 0.5
    idx = np.arange(n) - centre
    sq = (idx[:, None] + sub[None, :]) ** 2  # (voxel, sub-row) squared offsets along y or z
    x_lo, x_hi = idx - 0.5, idx + 0.5
    cover = np.zeros((n, n, n), dtype=np.float64)
    for iz in range(n):
        h2 = r * r - sq[iz][:, None, None] - sq[None, :, :]  # (sub z, y, sub y)
        rows = np.flatnonzero((h2 > 0).any(axis=(0, 2)))
        if rows.size == 0:
            continue
        h = np.sqrt(np.maximum(h2[:, rows], 0.0))[..., None]  # half chord of each sub-row
        overlap = np.clip(np.minimum(x_hi, h) - np.maximum(x_lo, -h), 0.0, 1.0)
        cover[iz, rows] = overlap.mean(axis=(0, 2))
    data = cover * value
    if dt.kind in "iu":
        data = np.rint(data)
    meta = {"centre": (centre,) * 3, "radius_vox": r, "value": value}
    return Volume(data=data.astype(dt), name="ball", source=source, meta=meta)


def _marschner_lobb(source: str, size: int, dtype: str) -> Volume:
    n = size
    axis = np.linspace(-1.0, 1.0, n)
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    rho = marschner_lobb(x, y, z)
    dt = np.dtype(dtype)
    if dt.kind == "u":
        rho = np.rint(rho * np.iinfo(dt).max)
    scale = float(np.iinfo(dt).max) if dt.kind == "u" else 1.0
    meta = {"fm": ML_FM, "alpha": ML_ALPHA, "domain": (-1.0, 1.0), "scale": scale}
    step = 2.0 / (n - 1)
    return Volume(
        data=rho.astype(dt),
        spacing=(step, step, step),
        name="marschner-lobb",
        source=source,
        meta=meta,
    )


def _head_tissue(z: np.ndarray, y: np.ndarray, x: np.ndarray, h: np.float32) -> np.ndarray:
    """Noise-free HU of the head at normalised coordinates ``z`` x ``y`` x ``x``."""
    Z, Y, X = z[:, None, None], y[None, :, None], x[None, None, :]
    shape = (len(z), len(y), len(x))

    def cover(d):  # fraction of the voxel inside the shape whose signed distance is d
        return np.clip(0.5 - d / h, 0.0, 1.0)

    def ellipsoid(c, a):  # first-order signed distance to an axis-aligned ellipsoid
        u = [(X - c[0]) / a[0], (Y - c[1]) / a[1], (Z - c[2]) / a[2]]
        f = u[0] ** 2 + u[1] ** 2 + u[2] ** 2
        g = 2.0 * np.sqrt((u[0] / a[0]) ** 2 + (u[1] / a[1]) ** 2 + (u[2] / a[2]) ** 2)
        return (f - 1.0) / np.maximum(g, 1e-6)

    def y_cylinder(cx, cz, r, top):  # vertical cylinder from below the box up to y = top
        return np.maximum(np.sqrt((X - cx) ** 2 + (Z - cz) ** 2) - r, Y - top)

    vol = np.full(shape, -1000.0, dtype=np.float32)

    def paint(d, value):  # blend ``value`` (scalar or array) in by partial coverage
        vol[...] += cover(d) * (value - vol)

    cranium_c, cranium_a = (0.0, 0.18, 0.02), (0.66, 0.74, 0.80)
    skin = _union(
        [
            ellipsoid(cranium_c, cranium_a),
            ellipsoid((0.0, -0.22, -0.12), (0.52, 0.50, 0.62)),  # face and jaw
            y_cylinder(0.0, 0.12, 0.36, -0.3),  # neck
            ellipsoid((0.0, -0.12, -0.74), (0.07, 0.16, 0.12)),  # nose
            ellipsoid((0.66, 0.05, 0.08), (0.05, 0.14, 0.09)),  # ears
            ellipsoid((-0.66, 0.05, 0.08), (0.05, 0.14, 0.09)),
        ]
    )
    paint(skin, 40.0)  # skin, scalp, muscle
    # skull: shell inside the scalp, thickness varying 0.045 .. 0.095 with direction
    outer = ellipsoid(cranium_c, tuple(a - 0.045 for a in cranium_a))
    theta = np.arctan2(Z - cranium_c[2], X)
    lat = np.clip((Y - cranium_c[1]) / cranium_a[1], -1.0, 1.0)
    thick = 0.07 + 0.02 * np.sin(3.0 * theta) * np.cos(2.0 * lat) + 0.005 * np.cos(5.0 * theta)
    vault = np.maximum(outer, -0.4 - Y)  # no skull below the skull base
    depth = np.clip(-outer / thick, 0.0, 1.0)
    bone = 1500.0 - 750.0 * np.sin(np.pi * depth) ** 2  # dense tables, spongy diploe
    paint(np.maximum(vault, -(outer + thick)), bone)
    # inside the skull: the floor rises toward the front (anterior fossa above the eyes)
    floor = -0.2 + 0.9 * np.maximum(0.0, -(Z + 0.25))
    inner = np.maximum(outer + thick, floor - Y)
    paint(inner, 8.0)  # CSF around the brain
    paint(inner + 0.02, 35.0)  # brain
    paint(ellipsoid((0.0, 0.22, 0.05), (0.42, 0.38, 0.5)), 28.0)  # white matter
    for side in (-1.0, 1.0):
        paint(ellipsoid((0.1 * side, 0.24, 0.05), (0.06, 0.1, 0.28)), 5.0)  # ventricles
    paint(np.maximum(np.abs(Y - floor + 0.025) - 0.025, outer + thick), 900.0)  # skull base
    for side in (-1.0, 1.0):
        paint(ellipsoid((0.26 * side, -0.1, -0.56), (0.14, 0.13, 0.14)), -90.0)  # orbit fat
        paint(ellipsoid((0.26 * side, -0.1, -0.59), (0.11, 0.11, 0.11)), 12.0)  # eyeball
    paint(ellipsoid((0.0, -0.3, -0.5), (0.17, 0.1, 0.12)), -1000.0)  # maxillary sinus
    paint(ellipsoid((0.0, 0.28, -0.66), (0.1, 0.06, 0.04)), -1000.0)  # frontal sinus
    arch = ellipsoid((0.0, -0.5, -0.1), (0.34, 10.0, 0.42))  # elliptic cylinder along y
    paint(_intersect([arch, -(arch + 0.05), Z, np.abs(Y + 0.53) - 0.07]), 1300.0)  # mandible
    paint(
        _intersect(
            [np.abs(np.abs(X) - 0.31) - 0.025, np.abs(Z - 0.04) - 0.06, np.abs(Y + 0.4) - 0.17]
        ),
        1300.0,
    )
    paint(_intersect([arch + 0.01, -(arch + 0.06), Z + 0.15, np.abs(Y + 0.41) - 0.035]), 2000.0)
    paint(y_cylinder(0.0, 0.3, 0.08, -0.22), 900.0)  # cervical spine
    paint(y_cylinder(0.0, 0.3, 0.045, -0.24), 300.0)  # marrow
    paint(y_cylinder(0.0, 0.0, 0.06, -0.35), -1000.0)  # airway
    return vol


#: The head's declared value range: a CT scanner's 12-bit window in HU, which every voxel
#: is clipped to.  Declared rather than read off the data, so that a part of the head
#: (:func:`head_box`, generated on a worker) converts and classifies as the whole does.
HEAD_RANGE = (-1024, 3071)


def head_axes(size: int, z_spacing: float) -> tuple[np.ndarray, np.ndarray, np.float32]:
    """The head's normalised voxel-centre coordinates along z and along y (= x), float32,
    and the voxel size ``h`` its partial-volume blend uses."""
    n, nz = size, max(1, round(size / z_spacing))
    half = n / 2.0
    z = ((np.arange(nz) - (nz - 1) / 2.0) * z_spacing / half).astype(np.float32)
    y = ((np.arange(n) - (n - 1) / 2.0) / half).astype(np.float32)
    return z, y, np.float32(2.0 / n)


def head_box(
    size: int, noise: float, seed: int, z_spacing: float, z: slice, y: slice
) -> np.ndarray:
    """Voxels ``z x y x all x`` of the head phantom (int16 HU), bit for bit those of the
    whole phantom: every voxel is a function of its own coordinates (the layers are
    elementwise in float32, whole rows along x; the noise is counter-based,
    :func:`gaussian_noise`), so any box can be generated on its own."""
    zc, yc, h = head_axes(size, z_spacing)
    zs, ys = range(len(zc))[z], range(len(yc))[y]
    box = _head_tissue(zc[z], yc[y], yc, h)
    if noise > 0:
        shape = (len(zc), len(yc), len(yc))
        box += np.float32(noise) * gaussian_noise(seed, shape, zs, ys).astype(np.float32)
    return np.clip(np.rint(box), *HEAD_RANGE).astype(np.int16)


def gaussian_noise(seed: int, shape: tuple[int, int, int], zs: range, ys: range) -> np.ndarray:
    """Standard normal noise (float64) at voxels ``zs x ys x all x`` of a ``shape`` volume:
    Box-Muller on two uniforms per voxel, each the SplitMix64 hash of the seed and the
    voxel's index in the whole volume (a counter-based generator: no state, so a part of
    the volume draws exactly the numbers the whole does).

    # Ref: G. Steele, D. Lea, C. Flood, "Fast splittable pseudorandom number generators",
    #      OOPSLA 2014 (SplitMix64); Box and Muller, Ann. Math. Stat. 29 (1958).
    """
    _, ny, nx = shape
    z = np.arange(zs.start, zs.stop, dtype=np.uint64)[:, None, None]
    y = np.arange(ys.start, ys.stop, dtype=np.uint64)[None, :, None]
    x = np.arange(nx, dtype=np.uint64)[None, None, :]
    index = (z * np.uint64(ny) + y) * np.uint64(nx) + x
    key = _splitmix64(np.array([seed], dtype=np.uint64))[0]
    two = np.uint64(2)
    u1 = 1.0 - _unit(_splitmix64(index * two + key))  # (0, 1]: log is finite
    u2 = _unit(_splitmix64(index * two + key + np.uint64(1)))
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """SplitMix64's output function of ``x + golden gamma`` (uint64, wrapping)."""
    z = x + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _unit(bits: np.ndarray) -> np.ndarray:
    """The top 53 bits of uint64 hashes as floats in ``[0, 1)``."""
    return (bits >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def _head(source: str, size: int, noise: float, seed: int, z_spacing: float) -> Volume:
    """CT-like head, crown toward +y, face toward -z, in a box of ``size`` voxels along x
    and y (and ``round(size / z_spacing)`` slices along z) with the head filling ~80%.

    Layers are painted in order with a partial-volume blend ``coverage = clip(0.5 - d/h)``
    of an approximate signed distance ``d`` (``h`` = one voxel), then noise is added and
    the values clipped to :data:`HEAD_RANGE`, the volume's declared range.
    """
    nz = len(head_axes(size, z_spacing)[0])
    data = np.empty((nz, size, size), dtype=np.int16)
    for k in range(0, nz, _HEAD_SLAB):  # slabs bound the temporaries' memory
        data[k : k + _HEAD_SLAB] = head_box(
            size, noise, seed, z_spacing, slice(k, k + _HEAD_SLAB), slice(None)
        )
    meta = {
        "seed": seed,
        "noise": noise,
        "orientation": "crown +y, face -z",
        "value_range": HEAD_RANGE,
    }
    return Volume(
        data=data, spacing=(z_spacing, 1.0, 1.0), name="head", source=source, units="HU", meta=meta
    )


PHANTOMS: dict[str, PhantomInfo] = {
    "ball": PhantomInfo(
        "uniform ball, partial-volume edge, centre (n-1)/2, radius*n/2 voxels",
        {
            "size": Param(int, 64, 1, 1024, help="voxels per axis"),
            "radius": Param(float, 0.8, 1e-3, 1.0, help="fraction of half the box"),
            "value": Param(float, 200.0, -32768, 65535, help="value inside"),
            "dtype": Param(str, "uint8", choices=_DTYPES),
        },
        _ball,
    ),
    "marschner-lobb": PhantomInfo(
        "Marschner-Lobb 1994 test signal (f_M=6, alpha=0.25) sampled on [-1,1]^3",
        {
            "size": Param(int, 40, 2, 1024, help="lattice points per axis"),
            "dtype": Param(str, "float32", choices=("float32", "float64", "uint8", "uint16")),
        },
        _marschner_lobb,
    ),
    "head": PhantomInfo(
        "CT-like head in Hounsfield units: skin, skull, brain, ventricles, eyes, sinus, jaw",
        {
            "size": Param(int, 128, 8, 1024, help="voxels along x and y"),
            "noise": Param(float, 8.0, 0.0, 200.0, help="Gaussian noise sigma, HU"),
            "seed": Param(int, 0, 0, 2**31 - 1, help="noise seed"),
            "z_spacing": Param(float, 1.0, 0.25, 8.0, help="slice spacing; fewer, thicker slices"),
        },
        _head,
    ),
}


def make_phantom(name: str, **params: Any) -> Volume:
    """Build a built-in phantom.

    Parameters
    ----------
    name : str
        One of :data:`PHANTOMS`.
    **params
        Phantom parameters; each is checked against its type and range.

    Returns
    -------
    Volume
        ``source`` is the spec string (``"ball:size=32"``), ``name`` the phantom name.
    """
    info = _info(name, source=name)
    source = name + (":" + ",".join(f"{k}={v}" for k, v in params.items()) if params else "")
    values = info.defaults
    for key, value in params.items():
        if key not in info.params:
            raise InputError(
                f"unknown parameter {key!r}", source=source, key=key, allowed=", ".join(info.params)
            )
        values[key] = info.params[key].check(value, source, key)
    if "size" in values:  # built in float64, then converted: two copies at most
        n = int(values["size"])
        require_fits(16 * n**3, what=f"phantom {n}^3", source=source, key="size")
    return info.build(source, **values)  # type: ignore[misc]


def parse_phantom_spec(text: str) -> tuple[str, dict[str, Any]]:
    """Parse ``NAME[:key=value,...]``; values take the parameter's type.

    ``"head:size=64,noise=0"`` gives ``("head", {"size": 64, "noise": 0.0})``.  Unknown
    names and keys, malformed pairs and repeated keys raise :class:`InputError`.
    """
    name, _, rest = text.strip().partition(":")
    name = name.strip()
    info = _info(name, source=text)
    params: dict[str, Any] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = (s.strip() for s in item.partition("="))
        if not eq or not key or not value:
            raise InputError(f"expected key=value, got {item!r}", source=text, key="--phantom")
        if key in params:
            raise InputError(f"{key!r} given twice", source=text, key=key)
        if key not in info.params:
            raise InputError(
                f"unknown parameter {key!r}", source=text, key=key, allowed=", ".join(info.params)
            )
        params[key] = info.params[key].check(value, text, key)
    return name, params


def _info(name: str, source: str | None = None) -> PhantomInfo:
    if name not in PHANTOMS:
        raise InputError(
            f"unknown phantom {name!r}",
            source=source,
            key="phantom",
            allowed=", ".join(PHANTOMS),
        )
    return PHANTOMS[name]
