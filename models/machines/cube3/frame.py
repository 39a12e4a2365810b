"""What every Cube-3 rung asks: the refusals, the ``[buffers]`` model, the slab order.

# Ref: Pfister, Kaufman, Chiueh, "Cube-3", VolVis 1994 (abstract) [V]: 512^3 16-bit at
#      about 30 fps; ray casting with a 3D skewed volume memory, a modular fast bus, 2D
#      skewed buffers, 3D interpolation and shading units and a ray projection cone.
#      Bakalash, Kaufman, Xu, EGGH 1990 (abstract) [V]: a barrel shifter de-skews.  The
#      overview [V]: a global network aligns and distributes voxels from the memory to
#      parallel processing units; a circular cross-linked binary tree of voxel
#      combination units composites the samples; parallel and perspective.
#      US 5,594,842 [V]: trilinear samples evenly spaced along rays, gradients from
#      central differences.  The structure below (counts, latencies, the slab rule) [I].

The memory is read slice by slice along the view's principal axis (front to back), each
slice as beams of up to ``n = pipeline.count`` voxels (one memory cycle each: the
skewing makes them conflict-free); the barrel shifter de-skews a beam a cycle into the 2D
skewed buffers.  A sample whose principal coordinate lies in slab ``k`` (``floor`` of
it, front to back) needs slices up to ``k + 2`` (trilinear taps and central differences
[I]); the processing units take ``[buffers] units`` samples a clock, slab after slab.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, count, validate
from hwsim.spec.arch import ArchConfig
from models.frame import Frame
from models.machines.common.sections import refuse_sections

__all__ = [
    "LOOKAHEAD",
    "SHIFTER_LATENCY",
    "Cube3Buffers",
    "Cube3Faults",
    "check_frame",
    "parse_buffers",
    "slab_arrivals",
    "slab_schedule",
    "slice_beams",
    "tree_levels",
]

#: Slices past a sample's slab it needs (trilinear's next slice, the gradient's next) [I].
LOOKAHEAD = 2
#: Clocks of the barrel shifter (one beam rotated per clock) [I].
SHIFTER_LATENCY = 1


class Cube3Buffers(Schema):
    """``[buffers]``: the processing units (interpolation and shading, one sample a clock
    each) between the de-skewing network and the compositing tree."""

    units: count(1 << 16) = 512


@dataclass(frozen=True)
class Cube3Faults:
    """Structures the Cube-3 cycle model can break: the barrel shifter's rotation off by
    ``shifter_offset`` lanes."""

    shifter_offset: int = 0


def parse_buffers(arch: ArchConfig) -> Cube3Buffers:
    """``arch.buffers`` as :class:`Cube3Buffers` (checked when the file was loaded)."""
    return validate(arch.buffers, Cube3Buffers, arch.source, prefix="buffers")


def check_frame(frame: Frame) -> None:
    """Refuse what Cube-3's models cannot render: plans not cast along rays (every rung of
    the machine asks here)."""
    refuse_sections(frame.arch, "Cube-3")
    if frame.plan.kind != "ray":
        raise InputError(
            "Cube-3 casts rays at evenly spaced samples",
            source=frame.arch.source,
            key="pipeline.order",
            allowed="ray",
        )


def principal(frame: Frame) -> tuple[int, bool]:
    """The view's principal index axis and whether rays run toward increasing index."""
    central = frame.plan.camera.d[::-1] / np.asarray(frame.volume.spacing)
    kp = int(np.argmax(np.abs(central)))
    return kp, bool(central[kp] >= 0)


def slice_beams(shape: tuple[int, int, int], kp: int, modules: int) -> int:
    """Memory cycles of one slice across axis ``kp``: rows along the fastest other axis,
    each cut into beams of ``modules`` voxels."""
    a, b = (shape[ax] for ax in range(3) if ax != kp)
    return a * -(-b // modules)


def tree_levels(units: int) -> int:
    """Levels of the binary compositing tree over ``units`` samples."""
    return max(1, math.ceil(math.log2(units)))


def slab_arrivals(n_slices: int, beams: int) -> np.ndarray:
    """Clock at which each slice (front to back) is in the 2D buffers: read beam after
    beam, plus the shifter."""
    return (np.arange(n_slices) + 1) * beams + SHIFTER_LATENCY


def slab_schedule(loads: np.ndarray, arrivals: np.ndarray, units: int) -> tuple[int, int]:
    """End of the last slab and the clocks the units waited for the memory: slab ``k``
    starts when slice ``min(k + LOOKAHEAD, n - 1)`` has arrived and slab ``k - 1`` is done,
    and takes ``ceil(loads[k] / units)`` clocks."""
    n = arrivals.size
    end = waited = 0
    for k, load in enumerate(loads.tolist()):
        ready = int(arrivals[min(k + LOOKAHEAD, n - 1)])
        waited += max(0, ready - end)
        end = max(ready, end) + -(-load // units)
    return end, waited
