"""Volumes read a part at a time: what a frame split across workers reads.

# Ref: issue 20 (a 1024^3 frame split across Dask workers; memory that scales down).

A 1024^3 volume of 16-bit voxels is 2 GiB; a frame split across workers must not hold it
whole in any process.  A :class:`VolumeParts` describes where the voxels are (a file
read a box at a time with explicit reads, or the head phantom, generated a box at a time by
:func:`~hwsim.volumes.phantoms.head_box`) and hands out boxes of them; it pickles as that
description, never as voxels, so a worker on another machine opens its own.

:meth:`VolumeParts.volume` is the frame's :class:`Volume` without its voxels: the right
shape, type, spacing, units and value range (read once, a chunk at a time, for a file;
declared for the head), and a zero-strided placeholder for ``data`` that holds no
memory.  ``meta["parts"]`` marks it, and everything that would read its voxels whole
(:func:`models.units.voxel.converted_volume`, the ``mr`` preset's percentiles) refuses
it.  What reads in parts, reads :meth:`VolumeParts.box`.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.paths import input_file
from hwsim.spec.scene import VolumeSpec
from hwsim.volumes.modality import nrrd_modality
from hwsim.volumes.nrrd_file import _HEADER_ERRORS, byte_skip, nrrd_spacing
from hwsim.volumes.readers import HU_AIR_THRESHOLD, _stem, npy_header
from hwsim.volumes.volume import SUPPORTED_DTYPES, Volume

__all__ = ["VolumeParts", "volume_parts", "is_partial"]

#: Voxels read per chunk when a file's value range is read (bounded memory).
_CHUNK_VOXELS = 1 << 24
#: What ``--workers`` reads in parts.
READABLE = "the head phantom, or a .npy, raw-encoded .nrrd/.nhdr or .raw volume file"


def is_partial(volume: Volume) -> bool:
    """Whether ``volume`` is a :meth:`VolumeParts.volume` (its ``data`` holds no voxels)."""
    return "parts" in volume.meta


@dataclasses.dataclass(frozen=True)
class VolumeParts:
    """Where a volume's voxels are, read a box at a time (``kind``: ``"head"`` or
    ``"file"``).  Build one with :func:`volume_parts`."""

    kind: str
    shape: tuple[int, int, int]
    dtype: str
    spacing: tuple[float, float, float]
    name: str
    source: str
    units: str
    value_range: tuple[float, float]
    #: The head's parameters, or the file's ``(path, byte offset, byte order)``.
    args: tuple
    #: The modality the file's header names and where (:mod:`hwsim.volumes.modality`).
    modality: tuple[str, str] = ("", "")

    def volume(self) -> Volume:
        """The frame's volume, without voxels (see the module docstring)."""
        dtype = np.dtype(self.dtype)
        data = np.lib.stride_tricks.as_strided(
            np.zeros(1, dtype=dtype), shape=self.shape, strides=(0, 0, 0), writeable=False
        )
        meta = {"value_range": self.value_range, "parts": self}
        if self.modality[0]:
            meta["modality_from"] = self.modality[1]
        return Volume(
            data=data,
            spacing=self.spacing,
            name=self.name,
            source=self.source,
            units=self.units,
            meta=meta,
            modality=self.modality[0],
        )

    def box(self, z: slice, y: slice, x: slice | int = slice(None)) -> np.ndarray:
        """Voxels ``z x y x x`` (``x`` an int: one column, dropped from the shape), in the
        volume's type, bit for bit what the whole volume holds there."""
        if isinstance(x, int):
            return self._columns(z, y, x)
        return self._rows(z, y)[:, :, x]

    def _rows(self, z: slice, y: slice) -> np.ndarray:
        """Whole rows along x of ``z x y``: generated (the head), or read from the file
        with one ``pread`` per z (rows of one z are contiguous).  Explicit reads, not a
        memory map: a mapped file's pages count in the process's resident memory, and
        the kernel maps more of them than were touched (read-around, large folios)."""
        if self.kind == "head":
            from hwsim.volumes.phantoms import head_box

            return head_box(*self.args, z, y)
        path, offset, dtype = self.args
        file_dtype = np.dtype(dtype)
        nz, ny, nx = self.shape
        zs, ys = range(nz)[z], range(ny)[y]
        if ys.step != 1 or zs.step != 1:
            raise ValueError("boxes are read with unit steps")
        out = np.empty((len(zs), len(ys), nx), dtype=file_dtype)
        row = nx * file_dtype.itemsize
        fd = os.open(path, os.O_RDONLY)
        try:
            for i, k in enumerate(zs):
                start = offset + (k * ny + ys.start) * row
                got = os.preadv(fd, [memoryview(out[i]).cast("B")], start)
                if got != len(ys) * row:
                    raise InputError("ends early", source=self.source, key="shape")
        finally:
            os.close(fd)
        return out.astype(self.dtype, copy=False)

    def _columns(self, z: slice, y: slice, x: int) -> np.ndarray:
        """One x column over ``z x y``.  Whole ``(z, all y, all x)`` planes are read (or
        generated: the head's bits are those of whole rows along x) and kept while the
        requests come from nearby z (a band of slices along x moves a little per slice),
        so each plane is read about once per frame."""
        zs = range(self.shape[0])[z]
        planes = _PLANES.setdefault(self, {})
        for k in zs:
            if k not in planes:
                planes[k] = self._rows(slice(k, k + 1), slice(None))[0]
        window = 2 * max(len(zs), 1)
        for k in [k for k in planes if k < zs.start - window or k >= zs.stop + window]:
            del planes[k]
        return np.stack([planes[k][y, x] for k in zs]).reshape(len(zs), -1)


#: Whole z planes kept for x-column requests, per volume (a worker's band of them).
_PLANES: dict[VolumeParts, dict[int, np.ndarray]] = {}


def volume_parts(spec: VolumeSpec, base_dir: Path | None = None) -> VolumeParts:
    """The :class:`VolumeParts` of a scene's volume, or a one-line :class:`InputError`
    for a volume that cannot be read a part at a time."""
    if spec.phantom:
        return _head_parts(spec)
    if not spec.path:
        raise InputError("give a volume path or a phantom", key="volume")
    path = Path(spec.path).expanduser()
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    input_file(path)  # a FIFO, a device or a socket is never opened
    name = path.name.lower()
    modality = ("", "")
    if name.endswith(".npy"):
        layout = _npy_layout(path)
    elif name.endswith((".nrrd", ".nhdr")):
        layout, modality = _nrrd_layout(path)
    elif name.endswith(".raw"):
        layout = _raw_layout(path, spec)
    else:
        raise InputError(
            "cannot be read a part at a time", source=str(path), key="--workers", allowed=READABLE
        )
    data_path, offset, shape, dtype, spacing, units = layout
    if spec.spacing is not None:
        spacing = tuple(float(s) for s in spec.spacing)
    if dtype.newbyteorder("=") not in SUPPORTED_DTYPES:
        raise InputError(
            f"voxel type {dtype} cannot be read a part at a time",
            source=str(path),
            key="dtype",
            allowed=", ".join(str(d) for d in SUPPORTED_DTYPES),
        )
    if len(shape) != 3 or min(shape) < 1:
        raise InputError(
            f"shape {shape} is invalid", source=str(path), key="shape", allowed="3 axes >= 1"
        )
    nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize  # never allocated whole
    held = os.path.getsize(data_path) - offset
    if held != nbytes:
        raise InputError(
            f"holds {held} data bytes but its header declares {nbytes}",
            source=str(path),
            key="shape",
            allowed=f"exactly {nbytes} bytes",
        )
    parts = VolumeParts(
        kind="file",
        shape=shape,
        dtype=str(dtype.newbyteorder("=")),
        spacing=tuple(float(s) for s in spacing),
        name=_stem(path),
        source=str(path),
        units="",
        value_range=(0.0, 0.0),
        args=(str(data_path), offset, dtype.str),
        modality=modality,
    )
    lo, hi = _value_range(parts)
    if units == "" and np.dtype(parts.dtype).kind == "i" and lo <= HU_AIR_THRESHOLD:
        units = "HU"  # readers.hu_units' rule, on the range read once
    return dataclasses.replace(parts, value_range=(lo, hi), units=units)


def _head_parts(spec: VolumeSpec) -> VolumeParts:
    from hwsim.volumes.phantoms import HEAD_RANGE, PHANTOMS, head_axes, parse_phantom_spec

    params = dict(spec.params)
    source = spec.phantom + (
        ":" + ",".join(f"{k}={v}" for k, v in params.items()) if params else ""
    )
    if spec.phantom != "head":
        raise InputError(
            f"phantom {spec.phantom!r} is generated whole, not a part at a time",
            source=source,
            key="--workers",
            allowed=READABLE,
        )
    parse_phantom_spec(source)  # every parameter checked against its range
    values = {**PHANTOMS["head"].defaults, **params}
    size, z_spacing = int(values["size"]), float(values["z_spacing"])
    nz = len(head_axes(size, z_spacing)[0])
    spacing = (z_spacing, 1.0, 1.0) if spec.spacing is None else tuple(spec.spacing)
    return VolumeParts(
        kind="head",
        shape=(nz, size, size),
        dtype="int16",
        spacing=tuple(float(s) for s in spacing),
        name="head",
        source=source,
        units="HU",
        value_range=(float(HEAD_RANGE[0]), float(HEAD_RANGE[1])),
        args=(size, float(values["noise"]), int(values["seed"]), z_spacing),
    )


def _value_range(parts: VolumeParts) -> tuple[float, float]:
    """The file's smallest and largest voxel, read a chunk at a time (no memory map kept,
    so no page of it stays in this process); NaN or Inf refused as the reader does."""
    path, offset, dtype = parts.args
    dtype = np.dtype(dtype)
    total = int(np.prod(parts.shape))
    lo, hi = np.inf, -np.inf
    with open(path, "rb") as fh:
        fh.seek(offset)
        done = 0
        while done < total:
            count = min(_CHUNK_VOXELS, total - done)
            chunk = np.fromfile(fh, dtype=dtype, count=count)
            if chunk.size != count:
                raise InputError("ends early", source=parts.source, key="sizes")
            if chunk.dtype.kind == "f" and not np.isfinite(chunk).all():
                raise InputError(
                    "voxels are NaN or Inf",
                    source=parts.source,
                    key="data",
                    allowed="finite values",
                )
            lo, hi = min(lo, float(chunk.min())), max(hi, float(chunk.max()))
            done += count
    return lo, hi


def _npy_layout(path: Path):
    shape, fortran, dtype, offset = npy_header(path)
    if len(shape) != 3 or fortran:
        raise InputError(
            f"holds a {'Fortran-order ' if fortran else ''}array of shape {shape}",
            source=str(path),
            key="shape",
            allowed="a C-order (z, y, x) array",
        )
    return path, offset, tuple(int(n) for n in shape), np.dtype(dtype), (1.0, 1.0, 1.0), ""


def _nrrd_layout(path: Path):
    import nrrd

    src = str(path)
    try:
        with open(path, "rb") as fh:
            header = nrrd.read_header(fh)
            dtype = nrrd.reader._determine_datatype(header)
            offset = fh.tell()
    except (nrrd.NRRDError, *_HEADER_ERRORS) as exc:
        raise InputError(f"cannot read NRRD: {exc or type(exc).__name__}", source=src) from None
    encoding = str(header.get("encoding", "raw")).lower()
    if encoding != "raw":
        raise InputError(
            f"{encoding}-encoded data cannot be read a part at a time",
            source=src,
            key="encoding",
            allowed="raw (convert it once: hwsim convert FILE OUT.nrrd)",
        )
    sizes = [int(n) for n in header["sizes"]]
    if len(sizes) != 3:
        raise InputError(f"has {len(sizes)} axes", source=src, key="dimension", allowed="3")
    lines, skip = byte_skip(header, path)  # -1 or >= 0, refused otherwise
    if lines:
        raise InputError(f"line skip {lines}", source=src, key="line skip", allowed="0")
    detached = header.get("data file", header.get("datafile"))
    data_path = path
    if detached is not None:
        if not isinstance(detached, str):
            raise InputError("multi-file data", source=src, key="data file", allowed="one file")
        data_path = Path(detached) if os.path.isabs(detached) else path.parent / detached
        input_file(data_path, "data file")
        offset = 0
    shape = tuple(sizes[::-1])
    nbytes = int(np.prod(shape)) * dtype.itemsize
    # -1: the file's last bytes, never the header's (too short a file: the size check)
    offset = max(offset, os.path.getsize(data_path) - nbytes) if skip == -1 else offset + skip
    units = "HU" if "hounsfield" in str(header.get("content", "")).lower() else ""
    layout = data_path, offset, shape, dtype, tuple(nrrd_spacing(header, src)), units
    return layout, nrrd_modality(header, path)


def _raw_layout(path: Path, spec: VolumeSpec):
    if spec.shape is None or spec.dtype is None:
        raise InputError(
            "a .raw file needs an explicit shape (z, y, x) and dtype",
            source=str(path),
            key="shape" if spec.shape is None else "dtype",
        )
    dtype = np.dtype(spec.dtype).newbyteorder("<" if spec.byte_order == "little" else ">")
    return path, int(spec.header_bytes), tuple(int(n) for n in spec.shape), dtype, (1.0,) * 3, ""
