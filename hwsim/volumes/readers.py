"""Volume files by extension: ``.npy``, ``.nrrd``/``.nhdr``, ``.nii``/``.nii.gz``, ``.raw``
and DICOM series folders, all returned as a :class:`~hwsim.volumes.volume.Volume`.

Every reader returns data in ``(z, y, x)`` order (x fastest) with spacing in the same
order.  Voxel types outside :data:`~hwsim.volumes.volume.SUPPORTED_DTYPES` are converted
only when that is lossless; anything a user can get wrong raises
:class:`~hwsim.core.errors.InputError` naming the file.  The rules are in ``docs/volumes.md``.
"""

from __future__ import annotations

import dataclasses
import gzip
import logging
import struct
import tokenize
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.budget import require_fits
from hwsim.core.errors import InputError, one_line_warnings, warn_user
from hwsim.core.paths import input_file
from hwsim.spec.scene import VolumeSpec
from hwsim.volumes.modality import nifti_modality
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
    path = input_file(path, folder=True)  # a FIFO, a device or a socket is never opened
    src = str(path)
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
        from hwsim.volumes.nrrd_file import read_nrrd

        volume = read_nrrd(path)
    elif kind in (".nii", ".nii.gz"):
        with _nibabel_log(src):
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
    except (ValueError, OSError, EOFError, SyntaxError, tokenize.TokenError) as exc:
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
    _check_nifti_header(path)
    try:
        image = nib.load(src)  # the header only: the data stays on disk behind a proxy
        proxy = image.dataobj
        shape, dtype = tuple(int(n) for n in proxy.shape), np.dtype(proxy.dtype)
        slope, inter = float(proxy.slope), float(proxy.inter)
        zooms = [float(z) for z in image.header.get_zooms()]
        offset = int(proxy.offset)
        modality = nifti_modality(image.header)
    except Exception as exc:  # nibabel raises many types for damaged files
        _check_gzip_stream(path)  # a cut .nii.gz: say that, not nibabel's guess
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
    elif not done and _small_integers(slope, inter) and raw.size:
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


class _Collect(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextmanager
def _nibabel_log(source: str) -> Iterator[None]:
    """nibabel logs its header repairs to stderr itself and through the root logger; keep
    them, and pass each on as one :func:`warn_user` line only if the read succeeds (a
    failed read is hwsim's one error line, nothing else)."""
    logger = logging.getLogger("nibabel.global")
    handlers, propagate = list(logger.handlers), logger.propagate
    collect = _Collect()
    for handler in handlers:
        logger.removeHandler(handler)
    logger.addHandler(collect)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(collect)
        for handler in handlers:
            logger.addHandler(handler)
        logger.propagate = propagate
    for message in dict.fromkeys(collect.messages):
        warn_user(source, message)


#: ``sizeof_hdr`` of NIfTI-1 and NIfTI-2 headers, and where each keeps ``dim``.
_NIFTI_DIM = {348: (40, "h"), 540: (16, "q")}


def _check_nifti_header(path: Path) -> None:
    """Refuse a header nibabel would only log about: ``sizeof_hdr`` that is not 348 or
    540 in either byte order, or ``dim[0]`` (the number of dimensions) outside 1 .. 7.

    nibabel guesses the byte order from ``dim[0]``, so a bad one makes it log a cascade
    of repairs to stderr before it fails; this says the one thing that is wrong."""
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    try:
        with opener(path, "rb") as fh:
            head = fh.read(48)  # sizeof_hdr and dim[0] of either version
    except (OSError, EOFError, zlib.error) as exc:
        raise InputError(f"cannot read NIfTI: {exc}", source=str(path)) from None
    for order in "<>" if len(head) == 48 else "":
        size = struct.unpack(order + "i", head[:4])[0]
        if size in _NIFTI_DIM:
            offset, code = _NIFTI_DIM[size]
            ndim = struct.unpack_from(order + code, head, offset)[0]
            if not 1 <= ndim <= 7:
                raise InputError(
                    f"{ndim} dimensions", source=str(path), key="dim[0]", allowed="1 .. 7"
                )
            return
    raise InputError(
        "not a NIfTI header (sizeof_hdr is neither 348 nor 540, or the file is shorter)",
        source=str(path),
        key="sizeof_hdr",
        allowed="a NIfTI-1 or NIfTI-2 file",
    )


def _small_integers(*values: float) -> bool:
    """Whole numbers small enough that scaling int16 data by them stays in int64 (a
    damaged header's 1e30 slope is kept unapplied, as any other unscalable pair)."""
    return all(v.is_integer() and abs(v) < 2**31 for v in values)


def _check_gzip_stream(path: Path) -> None:
    """Refuse a ``.gz`` file whose stream is cut or damaged, saying how many bytes it
    holds (read 1 MiB at a time, nothing kept)."""
    if not path.name.lower().endswith(".gz"):
        return
    held = 0
    try:
        with gzip.open(path, "rb") as fh:
            while chunk := fh.read1(1 << 20):  # what is there, up to where it breaks
                held += len(chunk)
    except (OSError, EOFError, zlib.error) as exc:
        raise InputError(
            f"damaged gzip stream after {held} bytes: {exc}", source=str(path), key="size"
        ) from None


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
