"""Voxel conversion: a volume's values into the machine's unsigned voxel format (host side).

# Ref: architectures.md section 3 (VolumePro 500: 8-bit and 12-bit voxels; 8-bit data
#      indexes the 4096-entry LUT as value x 16, as VTK's VG500 mapper fills it).

Rules, in order:

1. unsigned integer data of ``d <= bits`` significant bits: ``raw = value << (bits - d)``
   (offset 0, scale ``2**-(bits - d)``);
2. signed integer data whose range fits: ``raw = value - min`` (offset ``min``, scale 1);
3. anything else (float data, too-wide integers): the value range ``[min, max]`` maps
   linearly onto ``[0, 2**bits - 1]``, rounding half up (a constant volume maps to 0).

``value = offset + scale * raw`` holds exactly for rules 1 and 2; rule 3 costs at most
half a raw step.  Nothing wraps.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from hwsim.volumes.volume import Volume

__all__ = [
    "VoxelMap",
    "convert_volume",
    "converted_volume",
    "converted_planes",
    "convert_values",
    "LATENCY",
    "II",
]

LATENCY = 0  # host-side conversion, no pipeline stage
II = 1


@dataclass(frozen=True, kw_only=True)
class VoxelMap:
    """``value = offset + scale * raw`` for raw voxels of ``bits`` bits."""

    bits: int
    offset: float
    scale: float

    def to_value(self, raw: np.ndarray) -> np.ndarray:
        return self.offset + self.scale * np.asarray(raw, dtype=np.float64)


#: Per-volume machine voxels, by width: successive frames of one volume (a turntable, a
#: sweep's design points) convert it once.  Read-only; dropped with the volume.
_CONVERTED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def converted_volume(volume: Volume, bits: int) -> tuple[np.ndarray, VoxelMap]:
    """:func:`convert_volume`, kept per volume and width (the array is read-only).  A
    volume read in parts (:mod:`hwsim.volumes.parts`) has no voxels to convert whole."""
    if "parts" in volume.meta:
        raise RuntimeError(f"{volume.source}: read a part at a time, never converted whole")
    per_width = _CONVERTED.setdefault(volume, {})
    if bits not in per_width:
        raw, vmap = convert_volume(volume, bits)
        raw.flags.writeable = False
        per_width[bits] = (raw, vmap)
    return per_width[bits]


class _Planes:
    """A volume's raw voxels read one z-plane at a time (``shape``, ``dtype``, ``[z]``)."""

    def __init__(self, volume: Volume, bits: int) -> None:
        self.volume, self.bits = volume, bits
        self.shape = volume.data.shape
        self.dtype = np.dtype(_raw_dtype(bits))

    def __getitem__(self, z: int) -> np.ndarray:
        raw = convert_values(self.volume.data[z], self.volume, self.bits)[0]
        return raw.astype(self.dtype)


def converted_planes(volume: Volume, bits: int):
    """:func:`converted_volume`'s array when it is kept (or the volume has one plane),
    else its z-planes converted as they are read (the same values: the rules are
    elementwise), for a reader that needs each plane once: a 512^3 volume then never
    holds a second whole copy of its voxels (0.27 GB) beside the reader's own."""
    data = volume.data
    if bits in _CONVERTED.get(volume, {}) or data.ndim < 3 or data.shape[0] <= 1:
        return converted_volume(volume, bits)[0]
    if "parts" in volume.meta:
        return converted_volume(volume, bits)[0]  # refuses, as converted_volume does
    return _Planes(volume, bits)


def convert_volume(volume: Volume, bits: int) -> tuple[np.ndarray, VoxelMap]:
    """The volume as raw voxels ``(z, y, x)`` in ``[0, 2**bits - 1]`` and its map: uint16
    for ``bits <= 16`` (a quarter of int64's bytes; every reader promotes what it reads),
    int64 above; converted a slice at a time, so no whole-volume temporary is made."""
    data = volume.data
    if data.ndim == 0 or data.shape[0] <= 1:
        raw, vmap = convert_values(data, volume, bits)
        return raw.astype(_raw_dtype(bits)), vmap
    out = np.empty(data.shape, dtype=_raw_dtype(bits))
    for z in range(data.shape[0]):
        out[z], vmap = convert_values(data[z], volume, bits)
    return out, vmap


def _raw_dtype(bits: int) -> type:
    return np.uint16 if bits <= 16 else np.int64


def convert_values(values: np.ndarray, volume: Volume, bits: int) -> tuple[np.ndarray, VoxelMap]:
    """Raw int64 voxels of any array of ``volume``'s values (the volume's rule, chosen by
    its dtype and value range, applied elementwise; e.g. block minima and maxima).  Every
    rule is non-decreasing in the value."""
    data = volume.data
    top = (1 << bits) - 1
    lo, hi = volume.value_range
    if data.dtype.kind == "u" and volume.bits <= bits and hi <= (1 << volume.bits) - 1:
        shift = bits - volume.bits
        return values.astype(np.int64) << shift, VoxelMap(bits=bits, offset=0.0, scale=2.0**-shift)
    if data.dtype.kind in "iu" and hi - lo <= top:
        return values.astype(np.int64) - int(lo), VoxelMap(bits=bits, offset=lo, scale=1.0)
    if hi <= lo:
        return np.zeros(values.shape, np.int64), VoxelMap(bits=bits, offset=lo, scale=1.0)
    scale = (hi - lo) / top
    raw = np.floor((values.astype(np.float64) - lo) / scale + 0.5).astype(np.int64)
    return np.clip(raw, 0, top), VoxelMap(bits=bits, offset=lo, scale=scale)
