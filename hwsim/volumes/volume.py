"""The one in-memory volume type every reader and phantom returns.

Axis order is ``(z, y, x)`` (C order, x fastest), voxel centres sit at integer index
coordinates, and ``spacing`` is the world size of one voxel step along each of those
axes, in the same ``(z, y, x)`` order (millimetres for medical data, 1.0 for phantoms).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from hwsim.core.errors import InputError

__all__ = ["Volume", "SUPPORTED_DTYPES", "SPACING_RANGE", "MAX_ANISOTROPY", "require_axes"]

#: Voxel spacings a volume may have (world units, millimetres for medical data): wide
#: enough for microscopy and geology, narrow enough that 1e-300 or 1e300 (a corrupt
#: header) is refused instead of overflowing the sample plans.
SPACING_RANGE = (1e-6, 1e6)
#: Largest ratio of the largest to the smallest spacing.  Rays are sampled in units of
#: the smallest spacing, so a ratio of r multiplies the samples along the other axes by
#: r; clinical scans stay below about 20.
MAX_ANISOTROPY = 1000.0

#: Voxel types a volume may hold.  Integer data keeps its type; ``bits`` says how many of
#: its bits are significant (8, 12 or 16 for the hardware's voxel formats; 32 for uint32
#: containers of fields).
SUPPORTED_DTYPES = (
    np.dtype(np.uint8),
    np.dtype(np.int8),
    np.dtype(np.uint16),
    np.dtype(np.int16),
    np.dtype(np.uint32),  # 32-bit voxels: containers of fields (VolumePro 1000)
    np.dtype(np.float32),
    np.dtype(np.float64),
)


@dataclass(frozen=True, kw_only=True, eq=False)
class Volume:
    """A scalar volume.

    Parameters
    ----------
    data : numpy.ndarray
        3-D array, axis order ``(z, y, x)``, one of :data:`SUPPORTED_DTYPES`, every
        value finite, no axis of length zero.  It is made read-only: renderers cache
        arrays derived from it.
    spacing : tuple of float
        World size of one voxel step along ``(z, y, x)``; each > 0 and finite.
    name : str
        Short label used in reports (file stem or phantom name).
    source : str
        Where the data came from (path, or phantom spec such as ``"ball:size=64"``).
    units : str
        Units of the voxel values, e.g. ``"HU"`` for CT; empty when unknown.
    bits : int
        Significant bits of integer data (8, 12, 16, or 32 for field containers); 0 for
        float data.
    modality : str
        Imaging modality the file's header names (``"CT"``, ``"MR"``, ...; DICOM's
        Modality tag, a NRRD field or comment, a NIfTI description); empty when it names
        none.  ``meta["modality_from"]`` says where it was read.  The ``auto`` transfer
        preset reads it (:mod:`hwsim.spec.preset_choice`).
    """

    data: np.ndarray
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    name: str = "volume"
    source: str = ""
    units: str = ""
    bits: int = 0
    meta: dict = field(default_factory=dict)
    modality: str = ""

    def __post_init__(self) -> None:
        where = self.source or self.name
        data = self.data
        if not isinstance(data, np.ndarray) or data.ndim != 3:
            raise InputError("volume data must be a 3-D array", source=where, key="shape")
        if data.dtype not in SUPPORTED_DTYPES:
            raise InputError(
                f"voxel type {data.dtype} is not supported",
                source=where,
                key="dtype",
                allowed=", ".join(str(d) for d in SUPPORTED_DTYPES),
            )
        require_axes(data.shape, where)
        if data.dtype.kind == "f" and not np.isfinite(data).all():
            bad = int(np.count_nonzero(~np.isfinite(data)))
            raise InputError(
                f"{bad} voxels are NaN or Inf", source=where, key="data", allowed="finite values"
            )
        spacing = tuple(float(s) for s in self.spacing)
        lo, hi = SPACING_RANGE
        if len(spacing) != 3 or not all(np.isfinite(s) and lo <= s <= hi for s in spacing):
            raise InputError(
                f"spacing {self.spacing} is out of range",
                source=where,
                key="spacing",
                allowed=f"three numbers in {lo:g} .. {hi:g}",
            )
        if max(spacing) / min(spacing) > MAX_ANISOTROPY:
            raise InputError(
                f"spacing {spacing} is {max(spacing) / min(spacing):.3g}x anisotropic",
                source=where,
                key="spacing",
                allowed=f"largest / smallest <= {MAX_ANISOTROPY:g}",
            )
        object.__setattr__(self, "spacing", spacing)
        # Renderers cache arrays derived from a volume (float copy, gradients), so its data
        # must not change under them: the array is made read-only (copy it to edit).
        data.flags.writeable = False
        if data.dtype.kind in "iu" and self.bits == 0:
            object.__setattr__(self, "bits", data.dtype.itemsize * 8)

    def __reduce__(self):
        # A volume read in parts (hwsim.volumes.parts) pickles as where its voxels are,
        # never as its placeholder data (which would be materialised whole).
        parts = self.meta.get("parts")
        if parts is not None:
            return (type(parts).volume, (parts,))
        return super().__reduce__()

    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxel counts along ``(z, y, x)``."""
        return tuple(int(n) for n in self.data.shape)  # type: ignore[return-value]

    @property
    def extent(self) -> np.ndarray:
        """World size of the volume's box along ``(z, y, x)``: ``shape * spacing``.

        The box spans half a voxel beyond the outer voxel centres on every side.
        """
        return np.asarray(self.shape, dtype=np.float64) * np.asarray(self.spacing)

    @property
    def value_range(self) -> tuple[float, float]:
        """Smallest and largest voxel value actually present, or, for a brick of a larger
        volume (``meta["value_range"]``, :meth:`brick`), the whole volume's: so every brick
        converts, classifies and scales gradients as the whole volume does."""
        if "value_range" in self.meta:
            lo, hi = self.meta["value_range"]
            return float(lo), float(hi)
        return self._data_range

    @functools.cached_property
    def _data_range(self) -> tuple[float, float]:
        """The data's extremes, read once (the data is read-only)."""
        return float(self.data.min()), float(self.data.max())

    def field(self, lsb: int, bits: int, name: str) -> Volume:
        """Bits ``lsb .. lsb + bits - 1`` of every (unsigned integer) voxel as a volume of
        ``bits``-bit voxels (uint16), for a machine's value path; ``meta`` keeps the
        whole voxels (``container``) and their width (``container_bits``), from which the
        other fields are read."""
        part = np.empty(self.data.shape, dtype=np.uint16)
        for z in range(self.data.shape[0]):  # a slice at a time: no whole int64 copy
            part[z] = (self.data[z].astype(np.int64) >> lsb) & ((1 << bits) - 1)
        return Volume(
            data=part,
            spacing=self.spacing,
            name=f"{self.name}.{name}",
            source=f"{self.source or self.name} field {name!r}",
            bits=bits,
            meta={**self.meta, "container": self.data, "container_bits": self.bits},
        )

    def brick(self, lo: tuple[int, int, int], hi: tuple[int, int, int], label: str) -> Volume:
        """Voxels ``lo .. hi - 1`` (z, y, x) as a volume of their own (a contiguous copy)
        that keeps this volume's spacing, units, bits, modality and value range."""
        box = (slice(lo[0], hi[0]), slice(lo[1], hi[1]), slice(lo[2], hi[2]))
        part = self.data[box]
        meta = {**self.meta, "value_range": self.value_range}
        if "container" in meta:  # a field's volume: its whole voxels, the same brick
            meta["container"] = np.ascontiguousarray(meta["container"][box])
        return Volume(
            data=np.ascontiguousarray(part),
            spacing=self.spacing,
            name=f"{self.name} {label}",
            source=f"{self.source or self.name} {label}",
            units=self.units,
            bits=self.bits,
            meta=meta,
            modality=self.modality,
        )

    @property
    def nbytes(self) -> int:
        """Bytes of voxel data."""
        return int(self.data.nbytes)


def require_axes(shape: tuple[int, ...], source: str) -> None:
    """Refuse a volume with an axis of length zero (errors name ``source``)."""
    if min(shape) == 0:
        raise InputError(
            f"axis of length zero in shape {shape}",
            source=source,
            key="shape",
            allowed="every axis >= 1",
        )
