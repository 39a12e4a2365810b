"""What every Cube-1 rung asks: the refusals, the beams of a frame and its latency.

# Ref: Bakalash, Kaufman, Xu, EGGH 1990 (abstract) [V]: Cube-1 (PCB) and Cube-2 (VLSI)
#      produce orthographic projections of 16^3 from predetermined directions; the
#      overview (shared/docs/reference/000_d6a752d96745b32a.txt, "Special-purpose rendering
#      hardware") [V]; projection in O(n^2 log n) (Kaufman & Bakalash, CG&A 1988) [V], "a
#      special bus which selects along a beam in only log time" (Kaufman et al., The CUBE
#      workstation, The Visual Computer 1988, abstract) [V].

A view is one of the six axis views (azimuth a multiple of 90 degrees at elevation 0,
or elevation +-90): every ray is then a beam of voxels parallel to a main axis, sampled on
voxel centres, which the skewed memory reads in one access when the beam is at most n
voxels long.  The beam's voxels then go onto the multiple-write bus, which selects the
front-most contributing one in ``ceil(log2 n)`` bus cycles (one per bit of the depth it
arbitrates on [I]); the selection of one beam ends before the next beam's starts (the
O(n^2 log n) frame [V]).  Iso is that selection; composite and MIP are the same beam
combined by the back end's units [I].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.models import Schema
from models.frame import Frame
from models.machines.common.sections import refuse_sections

__all__ = ["Cube1Buffers", "Cube1Faults", "beam_voxels", "check_frame", "bus_levels"]

#: Largest off-axis component of a view direction still taken as axis-parallel.
AXIS_TOLERANCE = 1e-9


class Cube1Buffers(Schema):
    """``[buffers]``: none: a beam goes from the modules straight onto the bus."""


@dataclass(frozen=True)
class Cube1Faults:
    """Structures the Cube-1 cycle model can break: a memory module whose reads return 0."""

    stuck_module: int | None = None


def bus_levels(modules: int) -> int:
    """Bus cycles of the multiple-write bus's selection along one beam of ``modules``
    voxels (``ceil(log2 n)``, at least one)."""
    return max(1, math.ceil(math.log2(modules)))


def check_frame(frame: Frame) -> None:
    """Refuse what Cube-1 cannot render: any view but the six axis views (every rung of
    the machine asks here)."""
    arch, plan = frame.arch, frame.plan
    refuse_sections(arch, "Cube-1")
    d = np.abs(plan.camera.d[::-1] / np.asarray(frame.volume.spacing))
    off = np.delete(d, int(np.argmax(d)))
    if plan.kind != "shear-warp" or off.max() > AXIS_TOLERANCE * d.max():
        raise InputError(
            "Cube-1 projects from predetermined directions only (beams along a main axis)",
            source=arch.source,
            key="view.azimuth",
            allowed="a multiple of 90 at view.elevation 0, or view.elevation +-90, parallel",
        )


def beam_voxels(frame: Frame) -> tuple[np.ndarray, np.ndarray, int]:
    """Every voxel of the buffer (int ``(k, 3)`` zyx), the beam along the view axis it
    belongs to, and the number of beams: the machine projects its whole buffer, so the
    beams are every column of the volume along the plan's principal axis."""
    shape = frame.volume.shape
    kp = frame.plan.principal_axis
    zyx = np.indices(shape).reshape(3, -1).T
    across = [ax for ax in range(3) if ax != kp]
    beam = zyx[:, across[0]] * shape[across[1]] + zyx[:, across[1]]
    return zyx.astype(np.int64), beam, shape[across[0]] * shape[across[1]]
