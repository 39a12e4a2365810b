"""DICOM files for reader tests: one home for the file meta, SOP identity and image tags
every test slice needs (found through ``pythonpath``; the tests of the readers and of the
preset choice write their series with it)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.uid import ExplicitVRLittleEndian, generate_uid


def write_slice(
    path: Path,
    stored: np.ndarray,
    *,
    sop_class: str,
    modality: str,
    position: Sequence[float],
    orientation: Sequence[float] = (1, 0, 0, 0, 1, 0),
    spacing: Sequence[float] = (1.0, 1.0),
    thickness: float = 1.0,
    bits_stored: int = 16,
    study: str = "1.2",
    series: str = "1.2.3",
    instance: int | None = None,
    rows_cols: tuple[int, int] | None = None,
    pixels: bool = True,
    **tags: object,
) -> None:
    """Write one single-frame image slice of unsigned stored values ``stored`` (2-D, saved
    as little-endian 16-bit words) to ``path``: explicit VR little endian, a fresh SOP
    instance UID, MONOCHROME2.  ``rows_cols`` overrides the Rows/Columns tags (a header
    that disagrees with the pixels); ``instance`` None leaves InstanceNumber out; ``pixels``
    False leaves PixelData out; ``tags`` are further attributes set as given
    (``RescaleIntercept=-1024``)."""
    ds = _dataset(sop_class)
    meta = ds.file_meta
    ds.SOPClassUID, ds.SOPInstanceUID = sop_class, meta.MediaStorageSOPInstanceUID
    ds.Modality, ds.StudyInstanceUID, ds.SeriesInstanceUID = modality, study, series
    ds.Rows, ds.Columns = rows_cols or stored.shape
    ds.SamplesPerPixel, ds.PhotometricInterpretation = 1, "MONOCHROME2"
    ds.BitsAllocated, ds.BitsStored, ds.HighBit = 16, bits_stored, bits_stored - 1
    ds.PixelRepresentation = 0
    ds.PixelSpacing, ds.SliceThickness = list(spacing), thickness
    ds.ImageOrientationPatient = list(orientation)
    ds.ImagePositionPatient = [float(v) for v in position]
    if instance is not None:
        ds.InstanceNumber = instance
    for name, value in tags.items():
        setattr(ds, name, value)
    if pixels:
        ds.PixelData = np.asarray(stored).astype("<u2").tobytes()
    ds.save_as(path, enforce_file_format=True)


def write_dicomdir(path: Path, file_set_id: str = "SERIES") -> None:
    """Write a DICOMDIR (media storage directory) file to ``path``."""
    from pydicom.uid import MediaStorageDirectoryStorage

    ds = _dataset(MediaStorageDirectoryStorage)
    ds.FileSetID = file_set_id
    ds.save_as(path, enforce_file_format=True)


def _dataset(sop_class: str) -> Dataset:
    """An empty dataset with its file meta: explicit VR little endian, a fresh UID."""
    meta = FileMetaDataset()
    meta.MediaStorageSOPClassUID = sop_class
    meta.MediaStorageSOPInstanceUID = generate_uid()
    meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds = Dataset()
    ds.file_meta = meta
    return ds
