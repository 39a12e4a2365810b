"""Samples interpolated from a machine's own copy of the volume at the samples' taps:
what a family whose sampling unit is not the slice datapath (texture units, a resampling
unit) hands the back end.

# Ref: models/units/interp.py (the interpolator formats); models/functional.py
#      (``TapSource``, the same arithmetic on the functional rung's arrays).

The arrays are the volume's raw voxels (or, pre-classified, its RGBA channels) and its
voxel gradients, promoted once per frame; a :class:`TapSamples` interpolates one step's
samples from them with the datapath's interpolator, so a machine that fetches through it
gives the functional rung's bits.
"""

from __future__ import annotations

import numpy as np

from models.units import interp as interp_unit

__all__ = ["TapSamples", "VoxelArrays"]


class VoxelArrays:
    """The volume of one frame as the sampling unit holds it: values (or pre-classified
    RGBA), and voxel gradients when the scene needs gradients, promoted."""

    def __init__(self, backend) -> None:
        be = self.be = backend
        cfg = be.dp.interp
        self.value = interp_unit.promote(be.raw.ravel(), cfg)
        self.rgba = None
        if be.pre_classified:
            self.rgba = [interp_unit.promote(c.ravel(), cfg) for c in be.classified_voxels(be.raw)]
        self.gradients = None
        if be.need_grad:
            from models.units import gradient as gradient_unit

            self.gradients = [
                interp_unit.promote(d, cfg) for d in gradient_unit.voxel_differences(be.raw)
            ]


class TapSamples:
    """One step's samples (a back-end sample source): ``taps`` of the whole step, ``pick``
    the entries of the samples the back end asks for."""

    def __init__(self, arrays: VoxelArrays, taps: interp_unit.InterpTaps, pick: np.ndarray):
        self.arrays, self.taps, self.pick = arrays, taps, pick
        self._cfg = arrays.be.dp.interp

    def _fetch(self, source: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        rows = self.pick if sel is None else self.pick[sel]
        t = self.taps
        sub = interp_unit.InterpTaps(t.idx[:, rows], t.frac[:, rows])
        return interp_unit.interpolate(source, sub, self._cfg, promoted=True)

    def value(self) -> np.ndarray:
        return self._fetch(self.arrays.value)

    def channels(self) -> list[np.ndarray]:
        return [self._fetch(c) for c in self.arrays.rgba]

    def gradient(self, sel: np.ndarray) -> np.ndarray:
        return np.stack([self._fetch(d, sel) for d in self.arrays.gradients], axis=1)
