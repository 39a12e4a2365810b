"""Transfer functions: RGBA over voxel value, with gradient-magnitude opacity modulation.

A :class:`TransferFunction` is piecewise linear over control values, clamped to its end
points.  Opacity is defined per unit sample distance (one smallest voxel spacing); the
renderers correct it for other spacings.  The hardware's 4096-entry lookup table is
*derived* from it (:meth:`TransferFunction.table`), so float and fixed-point renders
classify with the same function.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.paths import input_file
from hwsim.spec.preset_choice import choose_preset
from hwsim.spec.scene import TF_PRESETS, TransferSpec
from hwsim.volumes.volume import Volume

__all__ = ["TransferFunction", "resolve_transfer", "preset_points"]


@dataclass(frozen=True, kw_only=True, eq=False)
class TransferFunction:
    """Piecewise-linear RGBA classification.

    Parameters
    ----------
    values : ndarray, shape (K,)
        Ascending control values in the volume's units.
    rgba : ndarray, shape (K, 4)
        Colour and opacity at each control value, all in ``[0, 1]``.
    gradient_points : ndarray, shape (G, 2), optional
        ``(|gradient|, factor)`` rows; opacity is multiplied by the piecewise-linear
        factor.  ``|gradient|`` is in value units per world unit.
    illumination_points : ndarray, shape (G, 2), optional
        ``(|gradient|, factor)`` rows scaling the diffuse and specular light of a sample
        (VolumePro 500's gradient-magnitude illumination modulation).
    order : {"post", "pre"}
        Classify after interpolation (post) or classify voxels, then interpolate (pre).
    """

    values: np.ndarray
    rgba: np.ndarray
    gradient_points: np.ndarray | None = None
    order: str = "post"
    illumination_points: np.ndarray | None = None

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        rgba = np.asarray(self.rgba, dtype=np.float64)
        if values.ndim != 1 or rgba.shape != (values.size, 4) or values.size == 0:
            raise ValueError(f"bad transfer shapes {values.shape} and {rgba.shape}")
        if np.any(np.diff(values) < 0) or not np.isfinite(values).all():
            raise ValueError("transfer control values must be finite and ascending")
        if not (np.isfinite(rgba).all() and rgba.min() >= 0 and rgba.max() <= 1):
            raise ValueError("transfer RGBA must lie in [0, 1]")
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "rgba", rgba)
        for name in ("gradient_points", "illumination_points"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=np.float64))

    @property
    def modulates(self) -> bool:
        """Whether opacity depends on gradient magnitude."""
        return self.gradient_points is not None

    def classify(self, v: np.ndarray) -> np.ndarray:
        """RGBA of values ``v`` (any shape) as float64 ``(..., 4)`` in ``[0, 1]``."""
        v = np.asarray(v, dtype=np.float64)
        out = np.empty(v.shape + (4,), dtype=np.float64)
        for c in range(4):
            out[..., c] = np.interp(v, self.values, self.rgba[:, c])
        return out

    def opacity(self, v: np.ndarray) -> np.ndarray:
        """Opacity channel only (cheaper than :meth:`classify`)."""
        return np.interp(np.asarray(v, dtype=np.float64), self.values, self.rgba[:, 3])

    @property
    def modulates_illumination(self) -> bool:
        """Whether diffuse and specular light depend on gradient magnitude."""
        return self.illumination_points is not None

    def gradient_factor(self, gmag: np.ndarray) -> np.ndarray:
        """Opacity factor for gradient magnitudes ``gmag``; ones without modulation."""
        return _factor(self.gradient_points, gmag)

    def illumination_factor(self, gmag: np.ndarray) -> np.ndarray:
        """Diffuse and specular factor for gradient magnitudes ``gmag``; ones without."""
        return _factor(self.illumination_points, gmag)

    def visible_range(self) -> tuple[float, float] | None:
        """Smallest interval of values outside which opacity is zero (None: never visible)."""
        alpha = self.rgba[:, 3]
        nz = np.flatnonzero(alpha > 0)
        if nz.size == 0:
            return None
        lo = -np.inf if nz[0] == 0 else self.values[nz[0] - 1]
        hi = np.inf if nz[-1] == alpha.size - 1 else self.values[nz[-1] + 1]
        return float(lo), float(hi)

    def table(self, entries: int, lo: float, hi: float) -> np.ndarray:
        """Sample the function at ``entries`` evenly spaced values from ``lo`` to ``hi``.

        Entry ``i`` holds the RGBA at ``lo + i * (hi - lo) / (entries - 1)``; this is the
        float table the fixed-point classifier quantises into its LUT.
        """
        return self.classify(np.linspace(lo, hi, entries))


#: Per-volume percentiles of the ``mr`` preset (a volume's data is read-only).
_PERCENTILES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _percentiles(volume: Volume, lo: float, hi: float) -> tuple[float, float]:
    """The 40th and 99.5th percentile of the voxels above ``lo`` (kept per volume: a
    turntable or a sweep resolves the preset once per frame)."""
    cached = _PERCENTILES.get(volume)
    if (cached is None or cached[0] != (lo, hi)) and "parts" in volume.meta:
        raise InputError(
            "the mr preset reads percentiles of the whole volume",
            source=volume.source,
            key="transfer.preset",
            allowed="another preset or a transfer table with --workers (--transfer)",
        )
    if cached is None or cached[0] != (lo, hi):
        data = volume.data
        nonzero = data[data > lo]
        pair = np.percentile(nonzero, [40, 99.5]) if nonzero.size else (lo, hi)
        cached = _PERCENTILES[volume] = ((lo, hi), (pair[0], pair[1]))
    return cached[1]


def preset_points(name: str, volume: Volume) -> np.ndarray:
    """Control points ``(K, 5)`` of a named preset, fitted to ``volume`` where needed.

    ``ct``: Hounsfield units, translucent skin and opaque white bone.  ``mr``: a warm
    ramp between the 40th and 99.5th percentile of non-zero voxels.  ``ramp``: grey,
    opacity 0 to 0.5 across the value range.  ``warm``: a warm ramp over the value
    range.  ``auto``: one of these chosen from the volume's header and values
    (:func:`hwsim.spec.preset_choice.choose_preset`).
    """
    lo, hi = volume.value_range
    if hi <= lo:
        hi = lo + 1.0
    if name == "auto":
        name = choose_preset(volume)[0]
    if name == "ct":
        return np.array(
            [
                [-1024.0, 0.0, 0.0, 0.0, 0.0],
                [-400.0, 0.75, 0.45, 0.35, 0.0],
                [-150.0, 0.85, 0.55, 0.45, 0.02],
                [150.0, 0.90, 0.62, 0.52, 0.02],
                [250.0, 0.95, 0.88, 0.78, 0.0],
                [450.0, 0.96, 0.92, 0.84, 0.45],
                [1200.0, 1.0, 0.98, 0.92, 0.85],
                [3072.0, 1.0, 1.0, 1.0, 0.9],
            ]
        )
    if name == "mr":
        p40, p995 = _percentiles(volume, lo, hi)
        p995 = max(float(p995), float(p40) + 1e-6 * (hi - lo) + 1e-12)
        mid = 0.5 * (p40 + p995)
        return np.array(
            [
                [lo, 0.0, 0.0, 0.0, 0.0],
                [p40, 0.8, 0.45, 0.3, 0.0],
                [mid, 0.95, 0.75, 0.6, 0.08],
                [p995, 1.0, 0.95, 0.9, 0.6],
                [max(hi, p995), 1.0, 1.0, 1.0, 0.6],
            ]
        )
    if name == "ramp":
        return np.array([[lo, 0.0, 0.0, 0.0, 0.0], [hi, 1.0, 1.0, 1.0, 0.5]])
    if name == "warm":
        span = hi - lo
        return np.array(
            [
                [lo, 0.0, 0.0, 0.0, 0.0],
                [lo + 0.2 * span, 0.9, 0.5, 0.3, 0.0],
                [lo + 0.6 * span, 1.0, 0.85, 0.7, 0.35],
                [hi, 1.0, 1.0, 1.0, 0.8],
            ]
        )
    raise InputError(
        f"unknown transfer preset {name!r}", key="transfer.preset", allowed=", ".join(TF_PRESETS)
    )


def _factor(points: np.ndarray | None, gmag: np.ndarray) -> np.ndarray:
    gmag = np.asarray(gmag, dtype=np.float64)
    if points is None:
        return np.ones_like(gmag)
    return np.interp(gmag, points[:, 0], points[:, 1])


def resolve_transfer(
    spec: TransferSpec, volume: Volume, base_dir: Path | None = None
) -> TransferFunction:
    """Build the :class:`TransferFunction` a scene's ``[transfer]`` table describes."""
    grad = np.asarray(spec.gradient_opacity) if spec.gradient_opacity else None
    illum = np.asarray(spec.gradient_illumination) if spec.gradient_illumination else None
    if spec.points is not None:
        pts = np.asarray(spec.points, dtype=np.float64)
    elif spec.table is not None:
        pts = _table_points(spec, volume, base_dir or Path.cwd())
    else:
        pts = preset_points(spec.preset or "auto", volume)
    return TransferFunction(
        values=pts[:, 0],
        rgba=pts[:, 1:],
        gradient_points=grad,
        order=spec.order,
        illumination_points=illum,
    )


def _table_points(spec: TransferSpec, volume: Volume, base_dir: Path) -> np.ndarray:
    path = Path(spec.table)  # type: ignore[arg-type]
    if not path.is_absolute():
        path = base_dir / path
    source = str(path)
    key = "transfer.table"
    input_file(path, key)  # missing, a folder, a FIFO or a device: refused unopened
    if path.stat().st_size > 64 << 20:  # 65536 x 4 float64 is 2 MiB
        raise InputError("file is over 64 MiB", source=source, key=key, allowed="an (N, 4) .npy")
    try:
        table = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise InputError("file not found", source=source, key=key) from None
    except (ValueError, OSError, EOFError) as exc:
        raise InputError(f"not a readable .npy table: {exc}", source=source, key=key) from None
    if not isinstance(table, np.ndarray):  # an .npz archive
        table.close()
        raise InputError("an .npz archive, expected one .npy array", source=source, key=key)
    if table.dtype.kind not in "biuf":
        raise InputError(
            f"table of {table.dtype} values", source=source, key=key, allowed="real numbers"
        )
    if table.ndim != 2 or table.shape[1] != 4 or not 2 <= table.shape[0] <= 65536:
        raise InputError(
            f"table shape {table.shape} is invalid",
            source=source,
            key=key,
            allowed="(N, 4) with 2 <= N <= 65536",
        )
    table = table.astype(np.float64)
    if not (np.isfinite(table).all() and table.min() >= 0 and table.max() <= 1):
        raise InputError(
            "table entries must be finite and in 0 .. 1",
            source=source,
            key="transfer.table",
            allowed="0 .. 1",
        )
    if spec.table_range is not None:
        lo, hi = spec.table_range
    elif volume.data.dtype.kind in "iu":
        info = np.iinfo(volume.data.dtype)
        lo, hi = float(info.min), float(info.min + (1 << volume.bits) - 1)
    else:
        lo, hi = volume.value_range
        hi = hi if hi > lo else lo + 1.0
    values = np.linspace(lo, hi, table.shape[0])
    return np.column_stack([values, table])
