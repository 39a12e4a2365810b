"""DICOM series reader: one folder of single-frame slices of one series -> a Volume.

Slices are sorted by their position along the slice normal (``ImagePositionPatient``
dotted with the cross product of the two ``ImageOrientationPatient`` directions),
falling back to ``InstanceNumber`` when positions are missing.  ``RescaleSlope`` /
``RescaleIntercept`` are applied per slice; CT comes out as int16 Hounsfield units.

# Ref: DICOM PS3.3 C.7.6.2 (Image Plane module) and C.11.1.1.2 (Modality LUT / rescale).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.budget import require_fits
from hwsim.core.errors import InputError
from hwsim.volumes.readers import make_volume
from hwsim.volumes.volume import Volume

__all__ = ["read_dicom_series"]

_SAME_POSITION = 1e-4  # mm: two slices closer than this along the normal are duplicates


def read_dicom_series(folder: Path) -> Volume:
    """Read every DICOM image in ``folder`` (not recursive) as one ``(z, y, x)`` volume.

    Files that are not DICOM (a README) are skipped unless they are named ``*.dcm``; a
    DICOM file without pixel data is skipped (a DICOMDIR) unless it belongs to the series
    or is named ``*.dcm``: then the series has a hole and is refused naming that file.
    Raises :class:`InputError` naming the offending file on a second series, differing
    rows/columns or orientation, duplicate slice positions, multi-frame images or
    unreadable pixel data.

    Returns
    -------
    Volume
        ``z`` runs along the slice normal (ascending position), ``y`` down the rows,
        ``x`` along the columns.  Spacing ``(median slice distance, PixelSpacing[0],
        PixelSpacing[1])``.  ``bits`` is ``BitsStored`` when the rescaled values still fit
        that many bits, else the type's width.
    """
    folder = Path(folder)
    slices, bare = _read_files(folder)
    if not slices:
        raise InputError("no DICOM images in folder", source=str(folder), key="DICOM series")
    _check_no_bare_slice(bare, slices[0][1])
    _check_consistent(slices)
    slices, positions, how = _sort(slices)
    first = slices[0][1]
    rows, cols = int(first.get("Rows", 0) or 0), int(first.get("Columns", 0) or 0)
    # the stacked planes, then the rescaled copy: two float64-sized arrays at most
    require_fits(
        2 * 8 * len(slices) * rows * cols,
        what=f"DICOM series {len(slices)}x{rows}x{cols}",
        source=str(folder),
        key="Rows/Columns",
    )
    _check_regular(folder, positions)
    planes, slopes, inters = [], [], []
    for path, ds in slices:
        try:
            planes.append(np.asarray(ds.pixel_array))
        except Exception as exc:  # missing decoder, truncated pixel data
            raise InputError(f"cannot decode pixel data: {exc}", source=str(path)) from None
        slopes.append(float(ds.get("RescaleSlope", 1) or 1))
        inters.append(float(ds.get("RescaleIntercept", 0) or 0))
    raw = np.stack(planes)
    data = _rescale(raw, np.array(slopes), np.array(inters), str(folder))
    spacing = _numbers(first, "PixelSpacing", 2, slices[0][0])
    row_mm, col_mm = (1.0, 1.0) if spacing is None else (float(v) for v in spacing)
    if len(positions) > 1:
        z_mm = float(np.median(np.diff(positions)))
    else:
        z_mm = float(first.get("SpacingBetweenSlices", 0) or first.get("SliceThickness", 0) or 1)
    modality = str(first.get("Modality", ""))
    units = "HU" if modality == "CT" and str(first.get("RescaleType", "HU")) == "HU" else ""
    meta = {
        "modality": modality,
        "series_uid": str(first.get("SeriesInstanceUID", "")),
        "slice_order": how,
        "slice_positions": [float(p) for p in positions],
        "bits_stored": int(first.get("BitsStored", raw.dtype.itemsize * 8)),
        "files": [str(p) for p, _ in slices],
    }
    return make_volume(
        data,
        str(folder),
        spacing=(z_mm, row_mm, col_mm),
        name=folder.name or "dicom",
        units=units,
        bits=meta["bits_stored"],
        meta=meta,
        modality=(modality.strip().upper(), "DICOM Modality tag"),
    )


def _read_files(folder: Path) -> tuple[list[tuple[Path, Any]], list[tuple[Path, Any]]]:
    """The folder's DICOM files (regular files only: a FIFO is never opened), split into
    those with pixel data and those without; a damaged one is refused naming it."""
    import pydicom
    from pydicom.errors import InvalidDicomError

    slices: list[tuple[Path, Any]] = []
    bare: list[tuple[Path, Any]] = []
    for path in sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")):
        try:
            ds = pydicom.dcmread(path)
        except InvalidDicomError:
            if path.suffix.lower() == ".dcm":
                raise InputError("not a DICOM file", source=str(path)) from None
            continue
        except Exception as exc:  # pydicom raises many types for damaged files
            raise InputError(f"cannot read DICOM: {exc}", source=str(path)) from None
        (slices if "PixelData" in ds else bare).append((path, ds))
    return slices, bare


#: Largest departure of a slice distance from the median, as a share of the median, that
#: is still one regular spacing (scanners round positions to about 1e-3 mm).
SLICE_TOLERANCE = 0.01


def _check_regular(folder: Path, positions: np.ndarray) -> None:
    """Refuse a series whose slices are not evenly spaced (gaps, tilted or mixed stacks).

    Rendering it at the median distance would place slices at wrong depths in silence.
    """
    if len(positions) < 3:
        return
    steps = np.diff(positions)
    median = float(np.median(steps))
    worst = float(np.max(np.abs(steps - median)))
    if median <= 0 or worst > SLICE_TOLERANCE * median:
        raise InputError(
            f"slice positions are not evenly spaced: distances {steps.min():g} .. "
            f"{steps.max():g} mm around a median of {median:g} mm",
            source=str(folder),
            key="ImagePositionPatient",
            allowed=f"every distance within {SLICE_TOLERANCE:.0%} of the median "
            "(resample the series first)",
        )


def _check_no_bare_slice(bare: list[tuple[Path, Any]], first: Any) -> None:
    """Refuse a slice of the series that has no pixel data (a hole in the stack); other
    DICOM files without pixels (a DICOMDIR, a report of another series) are skipped."""
    series = first.get("SeriesInstanceUID")
    for path, ds in bare:
        same = series is not None and ds.get("SeriesInstanceUID") == series
        if same or path.suffix.lower() == ".dcm" or "Rows" in ds:
            raise InputError(
                "DICOM slice without pixel data",
                source=str(path),
                key="PixelData",
                allowed="every slice of the series holds its pixels",
            )


def _check_consistent(slices: list[tuple[Path, Any]]) -> None:
    first_path, first = slices[0]
    keys = ("SeriesInstanceUID", "Rows", "Columns", "ImageOrientationPatient")
    want = {k: first.get(k) for k in keys}
    for path, ds in slices:
        frames = int(ds.get("NumberOfFrames", 1) or 1)
        if frames != 1:
            raise InputError(
                f"multi-frame image ({frames} frames)",
                source=str(path),
                key="NumberOfFrames",
                allowed="single-frame slices",
            )
        for key in keys:
            got = ds.get(key)
            same = got == want[key]
            if key == "ImageOrientationPatient" and got is not None and want[key] is not None:
                got_v, want_v = _numbers(ds, key, 6, path), _numbers(first, key, 6, first_path)
                same = np.allclose(got_v, want_v, atol=1e-4)
            if not same:
                raise InputError(
                    f"{key} {got} differs from {want[key]} in {first_path.name}",
                    source=str(path),
                    key=key,
                    allowed="one series per folder, all slices the same size and orientation",
                )


def _sort(slices: list[tuple[Path, Any]]) -> tuple[list, np.ndarray, str]:
    """Slices in ascending position along the normal (or InstanceNumber) and positions."""
    have_pos = all(
        "ImagePositionPatient" in ds and "ImageOrientationPatient" in ds for _, ds in slices
    )
    if have_pos:
        iop = _numbers(slices[0][1], "ImageOrientationPatient", 6, slices[0][0])
        normal = np.cross(iop[:3], iop[3:])
        keys = [
            float(np.dot(_numbers(ds, "ImagePositionPatient", 3, path), normal))
            for path, ds in slices
        ]
        how = "position"
    else:
        missing = [p for p, ds in slices if "InstanceNumber" not in ds]
        if missing:
            raise InputError(
                "no ImagePositionPatient and no InstanceNumber: cannot order slices",
                source=str(missing[0]),
                key="InstanceNumber",
            )
        keys = [float(ds.InstanceNumber) for _, ds in slices]
        how = "instance"
    order = np.argsort(keys, kind="stable")
    slices = [slices[i] for i in order]
    keys_sorted = np.asarray(keys)[order]
    gaps = np.diff(keys_sorted)
    if gaps.size and gaps.min() < _SAME_POSITION:
        i = int(np.argmin(gaps))
        raise InputError(
            f"same slice {how} as {slices[i][0].name}",
            source=str(slices[i + 1][0]),
            key="ImagePositionPatient" if how == "position" else "InstanceNumber",
            allowed="one slice per position",
        )
    return slices, (keys_sorted if how == "position" else np.zeros(0)), how


def _numbers(ds: Any, key: str, count: int, path: Path) -> np.ndarray | None:
    """The multi-valued ``key`` of ``ds`` as ``count`` finite floats, None when absent;
    another count or a value that is not a finite number is refused naming the file."""
    if key not in ds:
        return None
    value = ds.get(key)
    items = [value] if isinstance(value, (str, bytes, float, int)) else list(value)
    try:
        numbers = np.array([float(v) for v in items], dtype=np.float64)
    except (TypeError, ValueError):
        numbers = np.full(0, np.nan)
    if numbers.size != count or not np.isfinite(numbers).all():
        raise InputError(
            f"{key} is {value!r}", source=str(path), key=key, allowed=f"{count} finite numbers"
        )
    return numbers


def _rescale(raw: np.ndarray, slopes: np.ndarray, inters: np.ndarray, source: str) -> np.ndarray:
    """Apply per-slice rescale; integer results keep the stored type or the first of
    int16/uint16 that holds them exactly, non-integer rescales give float32; values a
    float32 cannot hold (a slope of 1e300, NaN) are refused."""
    if np.all(slopes == 1) and np.all(inters == 0):
        return raw
    small = np.all(np.abs(slopes) < 2**31) and np.all(np.abs(inters) < 2**31)
    integral = small and np.all(slopes == np.round(slopes)) and np.all(inters == np.round(inters))
    if integral and raw.dtype.kind in "iu":
        values = raw.astype(np.int64) * slopes.astype(np.int64)[:, None, None]
        values += inters.astype(np.int64)[:, None, None]
        lo, hi = int(values.min()), int(values.max())
        for target in (raw.dtype, np.dtype(np.int16), np.dtype(np.uint16)):
            info = np.iinfo(target)
            if info.min <= lo and hi <= info.max:
                return values.astype(target)
    out = raw.astype(np.float64) * slopes[:, None, None] + inters[:, None, None]
    if not (np.isfinite(out).all() and np.abs(out).max() <= np.finfo(np.float32).max):
        raise InputError(
            f"rescaled values reach {np.abs(out).max():g}",
            source=source,
            key="RescaleSlope/RescaleIntercept",
            allowed="finite float32 values",
        )
    return out.astype(np.float32)
