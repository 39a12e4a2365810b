"""Cube-4 timing rules shared by its cycle and transaction models: the pipeline latency
and each ray's pixel-FIFO push (rules 4-5) and which pipeline evaluates a sample (rule 3).
The RTL top may not import this module (import-linter): its timing must be its own.

# Ref: docs/cycle.md (timing rules); architectures.md sections 1.1, 1.3 and 9.2.
"""

from __future__ import annotations

import numpy as np

from hwsim.golden.positions import SamplePlan
from models.machines.common.results import UNITS
from models.units import skew as skew_unit

__all__ = [
    "CUBE4_UNITS",
    "cube4_lanes",
    "cube4_latency",
    "cube4_pixel_pushes",
    "cube4_slots",
]

#: The pipeline units Cube-4 has (architectures.md 1.3's stage list; no crop unit).
CUBE4_UNITS = ("interp", "gradient", "classify", "shade", "composite")
#: Clocks of the slice-buffer read between the address stage and the interpolator.
SLICE_BUFFER_READ = 1
#: Clocks from a push into the pixel FIFO to the first clock the entry can leave.
PIXEL_FIFO_WRITE = 1


def cube4_latency(beam_cycles: int) -> int:
    """Clocks from a sample slot's issue to the first clock its ray's pixel can leave the
    pixel FIFO (timing rule 5 of docs/cycle.md), the same for every scene (the hardware is
    fixed, so every unit counts).

    ``skew.LATENCY`` (address and de-skew) + 1 (the slice-buffer read: a synchronous RAM)
    + ``C + 1`` (beam alignment: a cell is complete when its corner one beam and one voxel
    ahead has arrived) + ``C`` (gradient look-ahead: of a sample's six central-difference
    neighbours the next slice's arrives with the sample, through the slice FIFOs primed by
    rule 2; the next sample in the beam one clock later over the ring; the next beam's
    sample last, ``C`` clocks later through the beam FIFO) + the ``LATENCY`` of the units
    Cube-4 has (interpolation, gradient, classification, shading, compositing; it has no
    crop unit; the compositor's write-back pushes the ray into the pixel FIFO) + 1 (an
    entry pushed in one clock leaves the FIFO the next at the earliest).  The RTL top
    (rtl/top.py) is the timing reference this was checked against.

    # Ref: architectures.md section 1.3 items 4-5 (one-beam and one-slice delay FIFOs;
    #      gradients as central differences of interpolated samples of beams j-1..j+1).
    """
    C = int(beam_cycles)
    units = sum(UNITS[u].LATENCY for u in CUBE4_UNITS)
    return skew_unit.LATENCY + SLICE_BUFFER_READ + (C + 1) + C + units + PIXEL_FIFO_WRITE


def cube4_slots(
    pa: np.ndarray, pb: np.ndarray, n_a: int, n_b: int, P: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(a, b)``: the voxel each sample at in-slice index positions ``(pa, pb)`` is
    evaluated at (its nearest voxel, ``cell + (fraction >= 1/2)``, clamped to the ``n_a x
    n_b`` slice).  Its pipeline is ``(q + a + b) mod P`` and its slot in the slice period
    ``a ceil(n_b / P) + b div P`` (one beam of ``C`` clocks per ``a``)."""
    ca, cb = np.floor(pa), np.floor(pb)
    a = np.clip(ca.astype(np.int64) + (pa - ca >= 0.5), 0, n_a - 1)
    b = np.clip(cb.astype(np.int64) + (pb - cb >= 0.5), 0, n_b - 1)
    return a, b


def cube4_pixel_pushes(
    plan: SamplePlan, period_start: np.ndarray, n_a: int, n_b: int, P: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """When every ray of ``plan`` would be pushed into the pixel FIFO if nothing froze
    (timing rules 4-5), its pipeline and its base-plane ray number: ``(push clocks
    ascending, lanes, rays)`` in FIFO order (clock, then pipeline).

    A ray is pushed when the compositor writes back its last sample: ``latency - 1``
    clocks after that sample's slot ``a C + b div P`` of the period that evaluates its
    step (``period_start[j]``, stall-free clocks).  A perspective slice stretched by rule
    3 keeps the rule at the sample's voxel slot (the RTL top has no perspective to check
    it against).
    """
    C = -(-n_b // P)
    rays = np.arange(plan.ray_ids.size)
    j = plan.j_hi
    pos = plan.position(j, rays)
    kp = plan.principal_axis
    a_ax, b_ax = (ax for ax in range(3) if ax != kp)
    a, b = cube4_slots(pos[:, a_ax], pos[:, b_ax], n_a, n_b, P)
    q = np.rint(pos[:, kp]).astype(np.int64)
    lanes = (q + a + b) % P
    push = np.asarray(period_start, dtype=np.int64)[j] + a * C + b // P + cube4_latency(C) - 1
    order = np.lexsort((lanes, push))
    return push[order], lanes[order], plan.ray_ids[order]


def cube4_lanes(q: int, pa: np.ndarray, pb: np.ndarray, n_a: int, n_b: int, P: int) -> np.ndarray:
    """The Cube-4 pipeline that evaluates each sample of slice ``q`` at in-slice index
    positions ``(pa, pb)``: the memory module ``(q + a + b) mod P`` of its nearest voxel
    (:func:`cube4_slots`).  A slice takes as long as its busiest pipeline (timing rule 3
    of docs/cycle.md).

    # Ref: architectures.md section 1.1 (skewed memory, voxel (x, y, z) in module
    #      (x + y + z) mod P).
    """
    a, b = cube4_slots(pa, pb, n_a, n_b, P)
    return (q + a + b) % P
