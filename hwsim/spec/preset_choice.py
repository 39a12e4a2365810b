"""The ``auto`` transfer preset: which named preset a volume gets, and why.

The rule (documented in ``docs/scenes.md``, "The auto preset"), first match wins:

1. the modality the file's header names (:attr:`Volume.modality`): ``CT`` -> ``ct``,
   ``MR`` -> ``mr``;
2. units of Hounsfield (``volume.units == "HU"``: a CT DICOM series, a NRRD whose
   ``content`` says Hounsfield, signed integer data reaching -900, the head phantom) ->
   ``ct``;
3. the value distribution, from one pass over the voxels (a 256-bin histogram over the
   value range):

   * CT: at least 1% of the voxels at or below -500 (air in Hounsfield units) -> ``ct``;
   * MR: no negative value, a dark background (at least 20% of the voxels in the lowest
     1/16 of the value range) and tissue spread above it (the quartiles of the voxels
     above the background at least 1/16 of the range apart, over at least 32 of the 256
     bins) -> ``mr``;

4. anything else (a constant volume, a binary mask, a test signal) -> ``warm``, a ramp
   over the value range.

The choice is made once per loaded volume, before any rung runs
(:func:`hwsim.run.fidelity.render` rewrites the scene's ``auto`` to the chosen preset),
so every rung, the stats and the summary see the same preset.
"""

from __future__ import annotations

import dataclasses
import weakref

import numpy as np

from hwsim.spec.scene import TransferSpec
from hwsim.volumes.volume import Volume

__all__ = ["choose_preset", "resolve_auto", "AIR_HU", "BINS"]

#: A voxel at or below this is air in Hounsfield units (air is -1000 HU, fat about -100).
AIR_HU = -500.0
#: Share of the voxels that must be air for CT-like data.
AIR_SHARE = 0.01
#: Histogram bins over the value range; the lowest ``BACKGROUND_BINS`` are background.
BINS = 256
BACKGROUND_BINS = BINS // 16
#: MR-like: share of dark background, and the spread of the voxels above it (in bins).
BACKGROUND_SHARE = 0.2
SPREAD_BINS = BINS // 16
FILLED_BINS = 32
#: Slices read at a time for the histogram (bounded memory on large volumes).
_SLAB_VOXELS = 1 << 24

#: The choice per loaded volume (a turntable or a sweep asks once per frame).
_CHOSEN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def resolve_auto(spec: TransferSpec, volume: Volume) -> TransferSpec:
    """``spec`` with ``preset = "auto"`` replaced by the preset chosen for ``volume``
    (``chosen_by`` says why); any other spec unchanged."""
    if spec.preset != "auto" or spec.points is not None or spec.table is not None:
        return spec
    name, reason = choose_preset(volume)
    return dataclasses.replace(spec, preset=name, chosen_by=f"auto: {reason}")


def choose_preset(volume: Volume) -> tuple[str, str]:
    """The preset ``auto`` means for ``volume``, and the reason (see the module docstring)."""
    cached = _CHOSEN.get(volume)
    if cached is None:
        cached = _CHOSEN[volume] = _choose(volume)
    return cached


def _choose(volume: Volume) -> tuple[str, str]:
    if volume.modality in ("CT", "MR"):
        where = volume.meta.get("modality_from", "header modality")
        return volume.modality.lower(), f"{where} {volume.modality}"
    if volume.units == "HU":
        return "ct", "volume units HU"
    lo, hi = volume.value_range
    hist, air = _census(volume, lo, hi)
    total = int(hist.sum())
    if total and air >= AIR_SHARE * total:
        share = 100.0 * air / total
        return "ct", f"value distribution, {share:.0f}% of voxels <= {AIR_HU:g} (air in HU)"
    if lo >= 0 and hi > lo and _mr_like(hist):
        share = 100.0 * hist[:BACKGROUND_BINS].sum() / total
        return "mr", f"value distribution, no negative values, {share:.0f}% dark background"
    return "warm", "value distribution, neither CT-like nor MR-like"


def _mr_like(hist: np.ndarray) -> bool:
    """A dark background and tissue values spread above it."""
    total = hist.sum()
    tissue = hist[BACKGROUND_BINS:]
    if hist[:BACKGROUND_BINS].sum() < BACKGROUND_SHARE * total or not tissue.sum():
        return False
    cum = np.cumsum(tissue)
    q25, q75 = np.searchsorted(cum, [0.25 * cum[-1], 0.75 * cum[-1]])
    return bool(q75 - q25 >= SPREAD_BINS and np.count_nonzero(tissue) >= FILLED_BINS)


def _census(volume: Volume, lo: float, hi: float) -> tuple[np.ndarray, int]:
    """A ``BINS``-bin histogram over ``lo .. hi`` and the count of air voxels, read a slab
    of slices at a time (a volume read in parts, ``--workers``, box by box)."""
    parts = volume.meta.get("parts")
    nz, ny, nx = volume.shape
    step = max(1, _SLAB_VOXELS // max(1, ny * nx))
    hist = np.zeros(BINS, dtype=np.int64)
    air = 0
    top = hi if hi > lo else lo + 1.0
    for z in range(0, nz, step):
        box = slice(z, min(nz, z + step))
        slab = parts.box(box, slice(None)) if parts is not None else volume.data[box]
        hist += np.histogram(slab, bins=BINS, range=(lo, top))[0]
        if lo <= AIR_HU:
            air += int(np.count_nonzero(slab <= AIR_HU))
    return hist, air
