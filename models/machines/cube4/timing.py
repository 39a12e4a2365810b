"""Cube-4 timing rules shared by its cycle and transaction models: the pipeline latency
(rule 5), which pipeline evaluates a sample (rule 3) and the on-chip buffer capacities.

# Ref: docs/cycle.md (timing rules); architectures.md sections 1.1, 1.3 and 9.2.
"""

from __future__ import annotations

import numpy as np

from hwsim.arch import ArchConfig
from models.machines.common.results import UNITS, buffer_table
from models.units import skew as skew_unit

__all__ = ["cube4_buffers", "cube4_lanes", "cube4_latency"]


def cube4_latency(beam_cycles: int) -> int:
    """A Cube-4 pipeline's latency in clocks (timing rule 5 of docs/cycle.md), the same
    for every scene (the hardware is fixed, so every unit counts).

    ``skew.LATENCY`` (address and de-skew) + ``C + 1`` (beam alignment: a cell is complete
    when its corner one beam and one voxel ahead has arrived) + ``C`` (gradient look-ahead:
    of a sample's six central-difference neighbours the next slice's arrives with the
    sample, through the slice FIFOs primed by rule 2; the next sample in the beam one clock
    later over the ring; the next beam's sample last, ``C`` clocks later through the beam
    FIFO) + every unit's ``LATENCY``.

    # Ref: architectures.md section 1.3 items 4-5 (one-beam and one-slice delay FIFOs;
    #      gradients as central differences of interpolated samples of beams j-1..j+1).
    """
    C = int(beam_cycles)
    return skew_unit.LATENCY + (C + 1) + C + sum(u.LATENCY for u in UNITS.values())


def cube4_lanes(q: int, pa: np.ndarray, pb: np.ndarray, n_a: int, n_b: int, P: int) -> np.ndarray:
    """The Cube-4 pipeline that evaluates each sample of slice ``q`` at in-slice index
    positions ``(pa, pb)``: the memory module ``(q + a + b) mod P`` of its nearest voxel
    (``cell + (fraction >= 1/2)``, clamped to the ``n_a x n_b`` slice).  A slice takes as
    long as its busiest pipeline (timing rule 3 of docs/cycle.md).

    # Ref: architectures.md section 1.1 (skewed memory, voxel (x, y, z) in module
    #      (x + y + z) mod P).
    """
    ca, cb = np.floor(pa), np.floor(pb)
    a = np.clip(ca.astype(np.int64) + (pa - ca >= 0.5), 0, n_a - 1)
    b = np.clip(cb.astype(np.int64) + (pb - cb >= 0.5), 0, n_b - 1)
    return (q + a + b) % P


def cube4_buffers(arch: ArchConfig, C: int, T: int) -> dict[str, int]:
    """A Cube-4 machine's on-chip buffer capacities per pipeline (``[buffers]``, entries),
    checked against a volume of ``C`` clocks per beam and ``T`` per slice.  Defaults:
    sized for ``limits.max_volume``.  One copy for the cycle and transaction models."""
    n_max = max(arch.max_volume)
    c_max = -(-n_max // arch.pipelines)
    defaults = {
        "beam_fifo_entries": c_max + 1,  # architectures.md 9.2: n / P
        "slice_fifo_entries": n_max * c_max,  # 9.2: n^2 / P per slice delay
        "pixel_fifo_entries": n_max * n_max,  # one slice of base-plane pixels
    }
    return buffer_table(arch, defaults, {"beam_fifo_entries": C + 1, "slice_fifo_entries": T})
