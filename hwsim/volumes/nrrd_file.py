"""NRRD volumes (``.nrrd`` with attached data, ``.nhdr`` with a detached data file).

pynrrd parses the header; the voxels are read here, so every size is checked before
anything is allocated and every way a file can be wrong is one line naming it:

- ``encoding``: ``raw``, ``ascii``/``text``/``txt`` (whitespace-separated numbers, read
  a chunk of lines at a time), ``gzip``/``gz``, ``bzip2``/``bz2`` (inflated in bounded
  chunks and refused the moment they run past the declared size).
- ``line skip`` (>= 0) lines, then ``byte skip`` bytes, are skipped before the data.  For
  compressed data the byte skip counts decoded bytes.  ``byte skip: -1`` means "the data
  is the file's last bytes" and is allowed for raw data only (the NRRD spec's rule);
  any other negative skip is refused by name.
- The data must hold exactly what ``sizes`` x ``type`` declares: more or less is refused
  with both counts.

# Ref: NRRD file format, NRRD0004/0005 (teem.sourceforge.net/nrrd/format.html),
# fields "encoding", "line skip", "byte skip", "data file".
"""

from __future__ import annotations

import bz2
import os
import zlib
from pathlib import Path

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.paths import input_file
from hwsim.volumes.modality import nrrd_modality
from hwsim.volumes.readers import _stem, declare, make_volume
from hwsim.volumes.volume import Volume

__all__ = ["read_nrrd", "nrrd_spacing", "byte_skip", "TEXT_ENCODINGS"]

#: Compressed NRRD encodings, inflated in bounded chunks by :func:`_inflate`.
_DECOMPRESSORS = {
    "gzip": lambda: zlib.decompressobj(zlib.MAX_WBITS | 32),
    "gz": lambda: zlib.decompressobj(zlib.MAX_WBITS | 32),
    "bzip2": bz2.BZ2Decompressor,
    "bz2": bz2.BZ2Decompressor,
}
#: Names the NRRD spec gives ASCII-encoded data.
TEXT_ENCODINGS = ("ascii", "text", "txt")
_ENCODINGS = "raw, ascii (text, txt), gzip (gz), bzip2 (bz2)"
_TYPES = "signed and unsigned integers of 8 to 64 bits, float, double"
_CHUNK = 1 << 20
#: Exceptions pynrrd raises for a damaged header (StopIteration: no line at all).
_HEADER_ERRORS = (OSError, ValueError, EOFError, KeyError, TypeError, IndexError, StopIteration)


def read_nrrd(path: Path) -> Volume:
    """A NRRD volume; anything wrong with the file is one :class:`InputError` naming it."""
    import nrrd

    src = str(path)
    if path.stat().st_size == 0:
        raise InputError("empty file", source=src, allowed="a NRRD header and its data")
    try:
        with open(path, "rb") as fh:
            header = nrrd.read_header(fh)
            dtype = nrrd.reader._determine_datatype(header)
            if dtype.kind not in "iuf" or dtype.itemsize == 0:  # "block": opaque bytes
                raise InputError(
                    f"type {header.get('type')!r}", source=src, key="type", allowed=_TYPES
                )
            nbytes = declare(header["sizes"], dtype, src, key="sizes")
            data = _payload(path, fh, header, dtype, nbytes)
    except (nrrd.NRRDError, *_HEADER_ERRORS) as exc:
        why = str(exc) or type(exc).__name__
        raise InputError(f"cannot read NRRD: {why}", source=src) from None
    data = data.reshape(tuple(int(n) for n in header["sizes"][::-1]))
    spacing = nrrd_spacing(header, src)
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


def byte_skip(header: dict, path: Path) -> tuple[int, int]:
    """The header's ``(line skip, byte skip)``, checked against the NRRD spec's rules."""
    encoding = str(header.get("encoding", "raw")).lower()
    skip = int(header.get("byte skip", header.get("byteskip", 0)))
    lines = int(header.get("line skip", header.get("lineskip", 0)))
    if lines < 0:
        raise InputError(f"line skip {lines}", source=str(path), key="line skip", allowed=">= 0")
    if skip < -1 or (skip == -1 and encoding != "raw"):
        raise InputError(
            f"byte skip {skip} with {encoding} encoding",
            source=str(path),
            key="byte skip",
            allowed=">= 0, or -1 with raw encoding (the data is the file's last bytes)",
        )
    return lines, skip


def _payload(path: Path, fh, header: dict, dtype: np.dtype, nbytes: int) -> np.ndarray:
    """The flat voxel array of a NRRD whose header ``fh`` has just been read."""
    import nrrd

    encoding = str(header.get("encoding", "raw")).lower()
    if encoding != "raw" and encoding not in _DECOMPRESSORS and encoding not in TEXT_ENCODINGS:
        raise InputError(
            f"unknown encoding {encoding!r}", source=str(path), key="encoding", allowed=_ENCODINGS
        )
    lines, skip = byte_skip(header, path)
    detached = header.get("data file", header.get("datafile"))
    if not isinstance(detached, (str, type(None))):  # multi-file data: pynrrd reads it
        return np.ravel(nrrd.read_data(header, fh, str(path), index_order="C"))
    if detached is not None:
        data_path = Path(detached) if os.path.isabs(detached) else path.parent / detached
        fh = open(input_file(data_path, "data file"), "rb")
    try:
        for _ in range(lines):
            if not fh.readline():
                break  # the size check below says what is missing
        if encoding == "raw":
            return np.frombuffer(_raw(fh, skip, nbytes, path), dtype=dtype)
        if encoding in TEXT_ENCODINGS:
            fh.seek(skip, os.SEEK_CUR)
            return _text(fh, dtype, nbytes // dtype.itemsize, path)
        payload = _inflate(fh, _DECOMPRESSORS[encoding](), skip, nbytes, path)
        return np.frombuffer(payload, dtype=dtype)
    finally:
        if detached is not None:
            fh.close()


def _raw(fh, skip: int, nbytes: int, path: Path) -> bytes:
    """Exactly ``nbytes`` after ``skip`` (-1: the file's last ``nbytes``), or refused."""
    after_header = os.fstat(fh.fileno()).st_size - fh.tell()
    held = after_header if skip == -1 else after_header - skip
    if skip > after_header:
        raise InputError(
            f"byte skip {skip} is past the end of the data ({after_header} bytes)",
            source=str(path),
            key="byte skip",
            allowed=f"0 .. {after_header - nbytes}" if after_header >= nbytes else "0",
        )
    if held != nbytes and not (skip == -1 and held > nbytes):
        raise _size_error(path, held, nbytes)
    fh.seek(-nbytes if skip == -1 else skip, os.SEEK_END if skip == -1 else os.SEEK_CUR)
    return fh.read(nbytes)


def _text(fh, dtype: np.dtype, count: int, path: Path) -> np.ndarray:
    """``count`` whitespace-separated numbers of ``dtype``, parsed a chunk of lines at a
    time (an integer out of the type's range or a non-number is refused)."""
    out = np.empty(count, dtype=dtype)
    done = 0
    while lines := fh.readlines(_CHUNK):
        tokens = b" ".join(lines).split()
        if done + len(tokens) > count:
            raise _size_error(path, None, count, "values")
        try:
            out[done : done + len(tokens)] = np.array(tokens).astype(dtype)
        except (ValueError, OverflowError) as exc:
            why = str(exc).replace("np.bytes_(", "").replace(")", "")
            raise InputError(
                f"ASCII data: {why}", source=str(path), key="data", allowed=f"{dtype} numbers"
            ) from None
        done += len(tokens)
    if done != count:
        raise _size_error(path, done, count, "values")
    return out


def _inflate(fh, decompressor, skip: int, nbytes: int, path: Path) -> bytearray:
    """Inflate ``fh``, drop its first ``skip`` bytes and keep exactly ``nbytes`` more; any
    more or less is refused.

    Output is asked for at most one byte past what is wanted (and at most 64 MiB) at a
    time, and skipped bytes are never kept, so a stream that would inflate to gigabytes
    stops after ``skip + nbytes + 1`` bytes holding at most ``nbytes + 64 MiB``.
    """
    want = skip + nbytes
    out = bytearray()
    seen = 0  # decoded bytes so far, skipped ones included
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
            chunk = decompressor.decompress(pending, max_length=min(want + 1 - seen, 64 * _CHUNK))
            pending = b"" if bz else decompressor.unconsumed_tail
            out += memoryview(chunk)[max(0, skip - seen) :]
            seen += len(chunk)
            if seen > want:
                raise _size_error(path, None, nbytes)
    except (zlib.error, OSError, EOFError) as exc:
        raise InputError(f"damaged compressed data: {exc}", source=str(path)) from None
    if seen != want:
        raise _size_error(path, max(seen - skip, 0), nbytes)
    return out


def _size_error(path: Path, actual: int | None, declared: int, unit: str = "bytes") -> InputError:
    held = f"more than {declared}" if actual is None else str(actual)
    return InputError(
        f"NRRD data holds {held} {unit} but the header declares {declared}",
        source=str(path),
        key="sizes",
        allowed=f"exactly {declared} {unit}",
    )


def nrrd_spacing(header: dict, src: str) -> np.ndarray:
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
