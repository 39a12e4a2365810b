"""Sections of the VolumePro family at ray granularity (``transaction`` rung).

# Ref: docs/cycle.md "Timing rules (VolumePro family)" rule 7 (sections: bands of beams
#      processed one after another in the rays' drift direction, partial rays parked
#      off-chip and reloaded); architectures.md section 3 (VolumePro 500 sectioning).

With ``[overheads] section_width = S`` the beams of a slice are cut into bands of ``S``
rows, processed one after another (every sample slice of a band, then the next band)
in the direction the rays drift.  A ray whose samples cross from one band into the next
is *parked*: it leaves over the pixel bus at the end of the band and is reloaded (one
clock each) when the next band starts.  In shear-warp order a ray's row at step ``j`` is
its base-plane row plus the slice's shear offset, monotonic in ``j``, so the bands a ray
visits follow from its first and last rows: no sample position is computed.
"""

from __future__ import annotations

import numpy as np

from hwsim.core.errors import InputError
from hwsim.golden.positions import SamplePlan

__all__ = ["bands_of", "band_loads", "refuse_sections"]


def refuse_sections(arch, machine: str) -> None:
    """Refuse ``[overheads] section_width`` on a machine whose model has no sections
    (Cube-4, VIZARD II): every rung asks, so none charges what the others ignore."""
    if arch.section_width:
        raise InputError(
            f"{machine} renders the whole slice: the model has no sections",
            source=arch.source,
            key="overheads.section_width",
            allowed="0",
        )


def bands_of(plan: SamplePlan, width: int, n_a: int, a_ax: int, source: str) -> list[tuple]:
    """Row bands ``[a0, a1)`` in processing order (one band when ``width`` is 0 or >= n_a)."""
    if width <= 0 or width >= n_a:
        return [(0, n_a)]
    if plan.camera.perspective:
        raise InputError(
            "sections need rays that drift one way: perspective rays diverge",
            source=source,
            key="overheads.section_width",
            allowed="0 (no sectioning) for perspective views",
        )
    bands = [(a0, min(a0 + width, n_a)) for a0 in range(0, n_a, width)]
    delta = np.asarray(plan._delta)
    drift = float(delta[..., a_ax].ravel()[0]) if delta.size else 0.0
    return bands[::-1] if drift < 0 else bands


def band_loads(
    plan: SamplePlan, bands: list[tuple], n_a: int, finishing: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rays finishing at each step in each band, and rays parked at the end of each band.

    Returns
    -------
    finishing_by_band : numpy.ndarray
        ``(len(bands), n_steps)``: rays whose last sample is at that step, in that band.
    parked : numpy.ndarray
        ``(len(bands),)``: rays with samples in a band and their last sample in a later
        one (they leave at the band's end and are reloaded when the next band starts).
    """
    n_bands, n_steps = len(bands), plan.n_steps
    if n_bands == 1:
        return finishing[None, :].astype(np.int64), np.zeros(1, dtype=np.int64)
    ids = plan.ray_ids

    def rows_at(j: np.ndarray) -> np.ndarray:
        # The plan's own float expression (SamplePlan.position), then the row clamp.
        pa = ids // plan.shape[1] + plan.base_origin[0] + plan.offsets[j, 0]
        return np.clip(np.floor(pa), 0, n_a - 1).astype(np.int64)

    starts = np.array([a0 for a0, _ in bands])
    order = np.argsort(starts)

    def band(rows: np.ndarray) -> np.ndarray:  # position in processing order
        return order[np.searchsorted(starts[order], rows, side="right") - 1]

    first, last = band(rows_at(plan.j_lo)), band(rows_at(plan.j_hi))
    if np.any(first > last):
        raise AssertionError("a ray moved against the bands' processing order")
    by_band = np.zeros((n_bands, n_steps), dtype=np.int64)
    np.add.at(by_band, (last, plan.j_hi), 1)
    # Each ray is parked at the end of every band from its first to the one before its last.
    marks = np.zeros(n_bands + 1, dtype=np.int64)
    np.add.at(marks, first, 1)
    np.add.at(marks, last, -1)
    return by_band, np.cumsum(marks)[:n_bands]
