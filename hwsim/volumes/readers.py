"""Volume files by extension: ``.npy``, ``.nrrd``/``.nhdr``, ``.nii``/``.nii.gz``, ``.raw``
and DICOM series folders, all returned as a :class:`~hwsim.volumes.volume.Volume`.

Every reader returns data in ``(z, y, x)`` order (x fastest) with spacing in the same
order.  Voxel types outside :data:`~hwsim.volumes.volume.SUPPORTED_DTYPES` are converted
only when that is lossless; anything a user can get wrong raises
:class:`~hwsim.core.errors.InputError` naming the file.  The rules are in ``docs/volumes.md``.
"""

from __future__ import annotations

import bz2
import dataclasses
import gzip
import os
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.budget import require_fits
from hwsim.core.errors import InputError, one_line_warnings
from hwsim.spec.scene import VolumeSpec
from hwsim.volumes.modality import nifti_modality, nrrd_modality
from hwsim.volumes.volume import SUPPORTED_DTYPES, Volume, require_axes

__all__ = ["EXTENSIONS", "load_volume", "read_volume", "hu_units"]

#: File kinds :func:`read_volume` understands (a DICOM series is a folder).
EXTENSIONS = (".npy", ".nrrd", ".nhdr", ".nii", ".nii.gz", ".raw", "<DICOM folder>")

#: Signed integer data whose minimum is at or below this is taken to be Hounsfield units.
HU_AIR_THRESHOLD = -900


def load_volume(spec: VolumeSpec, base_dir: Path | None = None) -> Volume:
    """Load the volume a scene asks for: a phantom or a file.

    Parameters
    ----------
    spec : VolumeSpec
        ``phantom`` + ``params``, or ``path`` (+ ``shape``/``dtype``/... for ``.raw``).
        ``spec.spacing`` (``(z, y, x)``), when given, overrides the declared spacing.
    base_dir : Path, optional
        Folder a relative ``path`` is resolved against (the scene file's folder).

    Returns
    -------
    Volume
    """
    if spec.phantom:
        from hwsim.volumes.phantoms import make_phantom

        volume = make_phantom(spec.phantom, **dict(spec.params))
        if spec.spacing is not None:
            volume = dataclasses.replace(volume, spacing=tuple(spec.spacing))
        return volume
    if not spec.path:
        raise InputError("give a volume path or a phantom", key="volume")
    path = Path(spec.path).expanduser()
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    return read_volume(
        path,
        shape=spec.shape,
        dtype=spec.dtype,
        byte_order=spec.byte_order,
        header_bytes=spec.header_bytes,
        spacing=spec.spacing,
    )


def read_volume(
    path: str | Path,
    *,
    shape: tuple[int, int, int] | None = None,
    dtype: str | None = None,
    byte_order: str = "little",
    header_bytes: int = 0,
    spacing: tuple[float, float, float] | None = None,
) -> Volume:
    """Read a volume file, choosing the reader by extension (a folder is a DICOM series).

    Parameters
    ----------
    path : str or Path
        ``.npy``, ``.nrrd``, ``.nhdr``, ``.nii``, ``.nii.gz``, ``.raw`` or a DICOM folder.
    shape, dtype, byte_order, header_bytes
        Layout of a headerless ``.raw`` file: ``shape`` is ``(z, y, x)``; the file must
        hold exactly ``header_bytes + prod(shape) * itemsize`` bytes.  Refused for other
        formats, whose headers say all of this.
    spacing : tuple of float, optional
        ``(z, y, x)`` voxel spacing overriding the file's own (or the default 1.0).

    Returns
    -------
    Volume
        ``(z, y, x)`` data; ``units`` is ``"HU"`` for CT-like data (see :func:`hu_units`).
    """
    path = Path(path)
    src = str(path)
    if not path.exists():
        raise InputError("file not found", source=src)
    with one_line_warnings(src):
        volume = _read_kind(path, src, shape, dtype, byte_order, header_bytes)
    if spacing is not None:
        volume = dataclasses.replace(volume, spacing=tuple(float(s) for s in spacing))
    return volume


def _read_kind(path, src, shape, dtype, byte_order, header_bytes) -> Volume:
    kind = _kind(path)
    if kind != ".raw" and (shape is not None or dtype is not None or header_bytes):
        raise InputError(
            "shape, dtype and header_bytes only apply to .raw files", source=src, key="shape"
        )
    if kind == ".npy":
        volume = _read_npy(path)
    elif kind in (".nrrd", ".nhdr"):
        volume = _read_nrrd(path)
    elif kind in (".nii", ".nii.gz"):
        volume = _read_nifti(path)
    elif kind == ".raw":
        volume = _read_raw(path, shape, dtype, byte_order, header_bytes)
    else:
        from hwsim.volumes.dicom import read_dicom_series

        volume = read_dicom_series(path)
    return volume


def hu_units(data: np.ndarray, declared: str = "") -> str:
    """Units of voxel values: ``declared`` if the file states them, else ``"HU"`` for
    signed integer data whose minimum is <= -900 (CT air is -1000 HU), else ``""``."""
    if declared:
        return declared
    if data.dtype.kind == "i" and data.size and int(data.min()) <= HU_AIR_THRESHOLD:
        return "HU"
    return ""


# ------------------------------------------------------------------------ helpers


def _kind(path: Path) -> str:
    if path.is_dir():
        return "<DICOM folder>"
    name = path.name.lower()
    for ext in (".nii.gz", ".npy", ".nrrd", ".nhdr", ".nii", ".raw"):
        if name.endswith(ext):
            return ext
    raise InputError(
        f"unknown volume file type {path.suffix or path.name!r}",
        source=str(path),
        key="extension",
        allowed=", ".join(EXTENSIONS),
    )


def _stem(path: Path) -> str:
    name = path.name
    for ext in (".nii.gz", ".npy", ".nrrd", ".nhdr", ".nii", ".raw"):
        if name.lower().endswith(ext):
            return name[: -len(ext)]
    return name


def to_supported(data: np.ndarray, source: str) -> np.ndarray:
    """Native-endian, C-contiguous data of a supported type, converted only losslessly.

    Big-endian becomes native; ``bool`` becomes ``uint8``; ``float16`` becomes
    ``float32``; wider integers become ``uint16``/``int16`` when every value fits (an
    unsigned source prefers ``uint16``, a signed one ``int16``); ``uint32`` data that does
    not fit stays ``uint32`` (32-bit voxels: containers of fields, VolumePro 1000).
    Anything else raises.
    """
    dt = data.dtype
    wide_unsigned = dt.kind == "u" and dt.itemsize == 4
    if wide_unsigned and data.size and int(data.max()) <= np.iinfo(np.uint16).max:
        data = data.astype(np.uint16)  # a scalar that fits: the 16-bit formats
    elif dt.kind == "b":
        data = data.astype(np.uint8)
    elif dt.kind in "iuf" and dt.newbyteorder("=") in SUPPORTED_DTYPES:
        data = data.astype(dt.newbyteorder("="), copy=False)
    elif dt.kind == "f" and dt.itemsize == 2:
        data = data.astype(np.float32)
    elif dt.kind in "iu":
        lo, hi = (int(data.min()), int(data.max())) if data.size else (0, 0)
        order = (np.uint16, np.int16) if dt.kind == "u" else (np.int16, np.uint16)
        for target in order:
            info = np.iinfo(target)
            if info.min <= lo and hi <= info.max:
                data = data.astype(target)
                break
        else:
            raise InputError(
                f"{dt} values {lo} .. {hi} do not fit a 16-bit voxel type",
                source=source,
                key="dtype",
                allowed="values within int16 or uint16 range",
            )
    else:
        raise InputError(
            f"voxel type {dt} is not supported",
            source=source,
            key="dtype",
            allowed=", ".join(str(d) for d in SUPPORTED_DTYPES) + " (or losslessly convertible)",
        )
    return np.ascontiguousarray(data)


def honest_bits(data: np.ndarray, declared: int | None = None) -> int:
    """``declared`` significant bits if every value fits them (two's complement for
    signed types), else the full width of the type; 0 for float data."""
    if data.dtype.kind == "f":
        return 0
    full = data.dtype.itemsize * 8
    if not declared or declared >= full or not data.size:
        return full
    lo, hi = int(data.min()), int(data.max())
    if data.dtype.kind == "i":
        fits = -(1 << (declared - 1)) <= lo and hi < (1 << (declared - 1))
    else:
        fits = hi < (1 << declared)
    return declared if fits else full


def make_volume(
    data: np.ndarray,
    source: str,
    *,
    spacing: tuple[float, ...] = (1.0, 1.0, 1.0),
    name: str = "volume",
    units: str = "",
    bits: int | None = None,
    meta: dict | None = None,
    modality: tuple[str, str] = ("", ""),
) -> Volume:
    """Check shape, normalise the type and build the :class:`Volume` (errors name ``source``);
    ``modality`` is what the header names and where (:mod:`hwsim.volumes.modality`)."""
    if data.ndim != 3:
        raise InputError(
            f"expected 3-D data, got {data.ndim}-D with shape {data.shape}",
            source=source,
            key="shape",
            allowed="(z, y, x)",
        )
    require_axes(data.shape, source)
    data = to_supported(data, source)
    meta = dict(meta or {})
    if modality[0]:
        meta["modality_from"] = modality[1]
    return Volume(
        data=data,
        spacing=tuple(float(s) for s in spacing),  # type: ignore[arg-type]
        name=name,
        source=source,
        units=hu_units(data, units),
        bits=honest_bits(data, bits),
        meta=meta,
        modality=modality[0],
    )


# ------------------------------------------------------------------------ formats


def declare(shape, dtype: np.dtype, source: str, key: str = "shape") -> int:
    """Bytes a header declares for ``shape`` of ``dtype``, refused before any allocation
    when an axis is not a positive integer or the data would not fit the memory budget.

    Conversions to a supported type may need a second copy, so twice the bytes are asked.
    """
    dims = [int(n) for n in shape]
    if any(n < 1 for n in dims) or len(dims) == 0:
        raise InputError(
            f"axis of length zero in shape {tuple(dims)}",
            source=source,
            key=key,
            allowed="every axis >= 1",
        )
    nbytes = int(np.prod(dims, dtype=object)) * int(dtype.itemsize)
    require_fits(2 * nbytes, what=f"voxel data {'x'.join(map(str, dims))} {dtype}", source=source)
    return nbytes


def npy_header(path: Path) -> tuple[tuple[int, ...], bool, np.dtype, int]:
    """A ``.npy`` file's shape, Fortran order, dtype and data offset (the header only)."""
    try:
        with open(path, "rb") as fh:
            version = np.lib.format.read_magic(fh)
            read_header = (
                np.lib.format.read_array_header_1_0
                if version == (1, 0)
                else np.lib.format.read_array_header_2_0
            )
            shape, fortran, dtype = read_header(fh, max_header_size=1 << 16)
            return shape, fortran, dtype, fh.tell()
    except (ValueError, OSError, EOFError, SyntaxError) as exc:
        raise InputError(f"cannot read .npy header: {exc}", source=str(path)) from None


def _read_npy(path: Path) -> Volume:
    src = str(path)
    shape, _, dtype, offset = npy_header(path)
    if dtype.hasobject:
        raise InputError("holds Python objects", source=src, key="dtype", allowed="numbers")
    nbytes = declare(shape, dtype, src) if shape else dtype.itemsize
    actual = path.stat().st_size - offset
    if actual != nbytes:
        raise InputError(
            f"holds {actual} data bytes but its header declares {nbytes}",
            source=src,
            key="shape",
            allowed=f"exactly {nbytes} bytes",
        )
    try:
        data = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise InputError(f"cannot read .npy: {exc}", source=str(path)) from None
    if not isinstance(data, np.ndarray):
        raise InputError("expected one array, got an .npz archive", source=str(path))
    return make_volume(data, str(path), name=_stem(path))


#: Compressed NRRD encodings, inflated in bounded chunks by :func:`_inflate`.
_DECOMPRESSORS = {
    "gzip": lambda: zlib.decompressobj(zlib.MAX_WBITS | 32),
    "gz": lambda: zlib.decompressobj(zlib.MAX_WBITS | 32),
    "bzip2": bz2.BZ2Decompressor,
    "bz2": bz2.BZ2Decompressor,
}
_CHUNK = 1 << 20


def _read_nrrd(path: Path) -> Volume:
    """NRRD with attached or detached data, raw, ASCII, gzip or bzip2 encoded.

    The header is read first: the declared shape x type must fit the memory budget, a
    raw payload must be as long as declared, and a compressed one is inflated in 1 MiB
    chunks into a buffer of the declared size and refused the moment it runs past it.
    """
    import nrrd

    src = str(path)
    try:
        with open(path, "rb") as fh:
            header = nrrd.read_header(fh)
            dtype = nrrd.reader._determine_datatype(header)
            nbytes = declare(header["sizes"], dtype, src, key="sizes")
            data = _nrrd_payload(path, fh, header, dtype, nbytes)
    except (nrrd.NRRDError, OSError, ValueError, EOFError, KeyError, TypeError) as exc:
        raise InputError(f"cannot read NRRD: {exc}", source=src) from None
    data = data.reshape(tuple(int(n) for n in header["sizes"][::-1]))
    spacing = _nrrd_spacing(header, src)
    if data.ndim != 3:
        spacing = np.ones(3)  # make_volume refuses the shape with a clear message
    units = "HU" if "hounsfield" in str(header.get("content", "")).lower() else ""
    meta = {"nrrd_header": {k: str(v) for k, v in header.items()}}
    return make_volume(
        data,
        src,
        spacing=tuple(spacing),
        name=_stem(path),
        units=units,
        meta=meta,
        modality=nrrd_modality(header, path),
    )


def _nrrd_payload(path: Path, fh, header: dict, dtype: np.dtype, nbytes: int) -> np.ndarray:
    """The flat voxel array of a NRRD whose header ``fh`` has just been read."""
    import nrrd

    encoding = str(header.get("encoding", "raw")).lower()
    skip = int(header.get("byte skip", header.get("byteskip", 0)))
    lines = int(header.get("line skip", header.get("lineskip", 0)))
    detached = header.get("data file", header.get("datafile"))
    if encoding in ("ascii", "text", "txt") or not isinstance(detached, (str, type(None))):
        fh.seek(0)  # text and multi-file data: pynrrd, now that the size is known to fit
        return np.ravel(nrrd.read_data(header, fh, str(path), index_order="C"))
    if encoding != "raw" and encoding not in _DECOMPRESSORS:
        raise InputError(
            f"unknown encoding {encoding!r}",
            source=str(path),
            key="encoding",
            allowed="raw, ascii, gzip, bzip2",
        )
    if detached is not None:
        data_path = Path(detached) if os.path.isabs(detached) else path.parent / detached
        if not data_path.is_file():
            raise InputError("data file not found", source=str(data_path), key="data file")
        fh = open(data_path, "rb")
    try:
        for _ in range(lines):
            fh.readline()
        if encoding == "raw":
            if skip == -1:
                fh.seek(-nbytes, os.SEEK_END)
            else:
                fh.seek(skip, os.SEEK_CUR)
            held = os.fstat(fh.fileno()).st_size - fh.tell()
            if held != nbytes:
                raise _size_error(path, held, nbytes)
            payload = fh.read(nbytes)
        else:
            if skip < 0:
                raise InputError(
                    "byte skip -1 with compressed data", source=str(path), key="byte skip"
                )
            payload = _inflate(fh, _DECOMPRESSORS[encoding](), skip, nbytes, path)
    finally:
        if detached is not None:
            fh.close()
    return np.frombuffer(payload, dtype=dtype)


def _inflate(fh, decompressor, skip: int, nbytes: int, path: Path) -> bytearray:
    """Inflate ``fh`` into exactly ``skip + nbytes`` bytes; any more or less is refused.

    Output is asked for at most one byte past what is wanted at a time, so a stream that
    would inflate to gigabytes stops after ``skip + nbytes + 1`` bytes.
    """
    want = skip + nbytes
    out = bytearray()
    pending = b""
    bz = isinstance(decompressor, bz2.BZ2Decompressor)
    try:
        while not decompressor.eof:
            if bz and not decompressor.needs_input:
                pending = b""  # output held back by max_length: drain it first
            elif not pending:
                pending = fh.read(_CHUNK)
                if not pending:
                    break
            out += decompressor.decompress(pending, max_length=want + 1 - len(out))
            pending = b"" if bz else decompressor.unconsumed_tail
            if len(out) > want:
                raise _size_error(path, None, nbytes)
    except (zlib.error, OSError, EOFError) as exc:
        raise InputError(f"damaged compressed data: {exc}", source=str(path)) from None
    if len(out) != want:
        raise _size_error(path, len(out) - skip, nbytes)
    return out[skip:]


def _size_error(path: Path, actual: int | None, nbytes: int) -> InputError:
    held = f"more than {nbytes}" if actual is None else str(actual)
    return InputError(
        f"NRRD data holds {held} bytes but the header declares {nbytes}",
        source=str(path),
        key="sizes",
        allowed=f"exactly {nbytes} bytes",
    )


def _nrrd_spacing(header: dict, src: str) -> np.ndarray:
    """``(z, y, x)`` spacing from ``spacings`` or the ``space directions`` vector lengths.

    A negative spacing is a flipped axis: its magnitude is the voxel size.  Zero or
    non-finite spacings are refused (an axis without a spacing, ``nan`` in pynrrd,
    defaults to 1.0).
    """
    ndim = len(header["sizes"])
    if "spacings" in header:
        spacing = np.abs(np.asarray(header["spacings"], dtype=np.float64))
        key = "spacings"
    elif "space directions" in header:
        dirs = np.asarray(header["space directions"], dtype=np.float64).reshape(ndim, -1)
        spacing = np.linalg.norm(dirs, axis=1)
        key = "space directions"
    else:
        return np.ones(3)
    if ndim == 3 and ((spacing == 0) | np.isinf(spacing)).any():
        raise InputError(
            f"spacing {spacing.tolist()} has a zero or infinite axis",
            source=src,
            key=key,
            allowed="finite numbers > 0",
        )
    return np.where(np.isnan(spacing), 1.0, spacing)[::-1]


def _read_raw(
    path: Path,
    shape: tuple[int, int, int] | None,
    dtype: str | None,
    byte_order: str,
    header_bytes: int,
) -> Volume:
    src = str(path)
    if shape is None or dtype is None:
        raise InputError(
            "a .raw file needs an explicit shape (z, y, x) and dtype",
            source=src,
            key="shape" if shape is None else "dtype",
            allowed="e.g. shape = [64, 128, 128], dtype = 'uint16'",
        )
    shape = tuple(int(n) for n in shape)  # type: ignore[assignment]
    if len(shape) != 3 or min(shape) < 1:
        raise InputError(
            f"shape {shape} is invalid", source=src, key="shape", allowed="3 ints >= 1"
        )
    if byte_order not in ("little", "big"):
        raise InputError(
            f"byte order {byte_order!r}", source=src, key="byte_order", allowed="little, big"
        )
    if header_bytes < 0:
        raise InputError("must be >= 0", source=src, key="header_bytes", allowed=">= 0")
    try:
        base = np.dtype(dtype)
    except TypeError:
        base = None
    if base is None or base.kind not in "biuf":
        raise InputError(
            f"unknown voxel type {dtype!r}",
            source=src,
            key="dtype",
            allowed=", ".join(str(d) for d in SUPPORTED_DTYPES),
        )
    dt = base.newbyteorder("<" if byte_order == "little" else ">")
    expected = header_bytes + declare(shape, dt, src)
    actual = path.stat().st_size
    if actual != expected:
        raise InputError(
            f"file holds {actual} bytes, shape {shape} of {base} needs {expected} "
            f"(header_bytes={header_bytes})",
            source=src,
            key="size",
            allowed=f"exactly {expected} bytes",
        )
    data = np.fromfile(path, dtype=dt, offset=header_bytes).reshape(shape)
    return make_volume(data, src, name=_stem(path))


def _read_nifti(path: Path) -> Volume:
    """NIfTI-1/2: nibabel's ``(x, y, z[, t])`` array transposed to ``(z, y, x)``.

    ``scl_slope``/``scl_inter`` are applied to integer data only when both are integers
    and the result fits the stored type (or else int16/uint16) exactly; otherwise the
    raw integers are kept and the pair is recorded in ``meta``.  Float data is always
    scaled.  The affine (voxel to world orientation) is recorded in ``meta``, not applied.
    """
    import nibabel as nib

    src = str(path)
    try:
        image = nib.load(src)  # the header only: the data stays on disk behind a proxy
        proxy = image.dataobj
        shape, dtype = tuple(int(n) for n in proxy.shape), np.dtype(proxy.dtype)
        slope, inter = float(proxy.slope), float(proxy.inter)
        zooms = [float(z) for z in image.header.get_zooms()]
        offset = int(proxy.offset)
        modality = nifti_modality(image.header)
    except Exception as exc:  # nibabel raises many types for damaged files
        raise InputError(f"cannot read NIfTI: {type(exc).__name__}: {exc}", source=src) from None
    _check_nifti_size(path, offset + declare(shape, dtype, src, key="dim"))
    try:
        raw = np.asarray(proxy.get_unscaled())
    except Exception as exc:
        raise InputError(f"cannot read NIfTI: {type(exc).__name__}: {exc}", source=src) from None
    if raw.ndim == 4 and raw.shape[3] == 1:
        raw = raw[..., 0]
    elif raw.ndim == 4:
        raise InputError(
            f"4-D image with {raw.shape[3]} time points", source=src, key="shape", allowed="t = 1"
        )
    meta: dict[str, Any] = {"affine": np.asarray(image.affine).tolist()}
    # NIfTI: slope 0 or NaN means "not scaled"
    done = not (np.isfinite(slope) and np.isfinite(inter) and slope) or (slope, inter) == (1, 0)
    if not done and raw.dtype.kind == "f":
        raw, done = (raw * slope + inter).astype(raw.dtype), True
    elif not done and slope.is_integer() and inter.is_integer() and raw.size:
        ends = np.array([raw.min(), raw.max()], dtype=np.int64) * int(slope) + int(inter)
        for target in (raw.dtype, np.dtype(np.int16), np.dtype(np.uint16)):
            info = np.iinfo(target)
            if info.min <= ends.min() and ends.max() <= info.max:
                raw = (raw.astype(np.int64) * int(slope) + int(inter)).astype(target)
                done = True
                break
    if not done:
        meta.update(scl_slope=slope, scl_inter=inter, scaled=False)
    data = np.ascontiguousarray(np.transpose(raw, tuple(range(raw.ndim))[::-1]))
    spacing = tuple(zooms[:3][::-1]) if raw.ndim == 3 else (1.0, 1.0, 1.0)
    return make_volume(data, src, spacing=spacing, name=_stem(path), meta=meta, modality=modality)


def _check_nifti_size(path: Path, expected: int) -> None:
    """Refuse data beyond what the header describes (nibabel ignores it silently)."""
    if path.name.lower().endswith(".gz"):
        actual = 0
        try:
            with gzip.open(path, "rb") as fh:  # streamed, and stopped past the declared size
                while actual <= expected and (chunk := fh.read(1 << 24)):
                    actual += len(chunk)
        except (OSError, EOFError, zlib.error) as exc:
            raise InputError(f"damaged gzip stream: {exc}", source=str(path)) from None
    else:
        actual = path.stat().st_size
    if actual != expected:
        held = f"more than {expected}" if actual > expected else str(actual)
        raise InputError(
            f"file holds {held} bytes but its header describes {expected}",
            source=str(path),
            key="size",
            allowed=f"exactly {expected} bytes",
        )
