"""What every cycle machine shares: its units, its result, buffer tables, elaboration.

# Ref: docs/cycle.md (timing rules, counters, "model only what the scene requires");
#      architectures.md section 9.2 (buffer sizes [I]).

One copy for the Cube-4 machine, the VolumePro slab machine, VIZARD II and the
transaction models that check the same buffers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.arch import ArchConfig
from hwsim.engine import Counters, DrainFifo
from hwsim.engine.metrics import derive
from hwsim.errors import InputError
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import crop as crop_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units import shade as shade_unit
from models.units import skew as skew_unit

__all__ = [
    "UNITS",
    "cube4_lanes",
    "CycleResult",
    "cube4_buffers",
    "slab_buffers",
    "buffer_table",
    "publish_pixel_bus",
    "frame_result",
    "elaborate_units",
    "cube4_latency",
]

#: The units of every Cube-4 pipeline, in dataflow order, with their models.
UNITS = {
    "interp": interp_unit,
    "gradient": gradient_unit,
    "classify": classify_unit,
    "shade": shade_unit,
    "composite": composite_unit,
    "crop": crop_unit,
}


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


@dataclass
class CycleResult:
    """What the cycle rung returns: image, exact cycles, raw counters, elaboration."""

    image: np.ndarray
    samples: int
    rays: int
    cycles: int
    counters: dict[str, Any] = field(default_factory=dict)
    elaborated_units: list[str] = field(default_factory=list)
    elided_units: list[str] = field(default_factory=list)
    derived: dict[str, Any] = field(default_factory=dict)


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


def slab_buffers(arch: ArchConfig, C: int) -> dict[str, int]:
    """A VolumePro-family machine's capacities per pipeline (``[buffers]``, entries),
    checked against a volume of ``C`` clocks per beam.  One copy for the cycle and
    transaction models.

    ``slab_buffer_entries`` defaults to ``8 n ceil(n / P)`` for ``n = max(max_volume)``:
    four mini-block slabs -- the sample window (voxel slices ``i0 - 1 .. i0 + 2``, up to
    three slabs) and one slab read ahead.
    """
    n_max = max(arch.max_volume)
    c_max = -(-n_max // arch.pipelines)
    defaults = {
        "slab_buffer_entries": 8 * n_max * c_max,
        "beam_fifo_entries": c_max + 1,
        "pixel_fifo_entries": n_max * n_max,
    }
    return buffer_table(arch, defaults, {"beam_fifo_entries": C + 1})


def buffer_table(
    arch: ArchConfig, defaults: dict[str, int], needs: dict[str, int]
) -> dict[str, int]:
    """The ``[buffers]`` table read against ``defaults`` (unknown keys and bad values
    refused naming the file and key) and checked against what this volume ``needs``."""
    table = dict(arch.buffers)
    out = {}
    for key, default in defaults.items():
        value = table.pop(key, default)
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            raise InputError(
                f"invalid {value!r}",
                source=arch.source,
                key=f"buffers.{key}",
                allowed="an integer >= 0",
            )
        out[key] = value
    if table:
        raise InputError(
            "unknown key",
            source=arch.source,
            key=f"buffers.{sorted(table)[0]}",
            allowed=", ".join(defaults),
        )
    for key, need in needs.items():
        if out[key] < need:
            raise InputError(
                f"{arch.name} cannot hold this volume's {key.split('_entries')[0]} "
                f"({need} entries per pipeline)",
                source=arch.source,
                key=f"buffers.{key}",
                allowed=f">= {need}",
            )
    return out


def publish_pixel_bus(counters: Counters, fifo: DrainFifo, drain: int) -> None:
    """The pixel bus's counters: pixels, busy cycles, peak occupancy, final drain."""
    counters.set("pixel_bus.pixels", fifo.pushed)
    counters.set("pixel_bus.busy_cycles", fifo.busy_cycles)
    counters.set("pixel_bus.max_occupancy", fifo.max_occupancy)
    counters.set("pixel_bus.drain_cycles", drain)


def frame_result(
    machine, image: np.ndarray, state, cycles: int, derive_samples: int | None = None
) -> CycleResult:
    """A frame's :class:`CycleResult` from a machine (``counters``, ``P``, ``arch``,
    ``elaborated``, ``elided``) and its back end's final state; derived metrics per
    ``derive_samples`` samples (default: the composited samples)."""
    raw = machine.counters.as_dict()
    derived = derive(
        raw,
        cycles=cycles,
        samples=state.samples if derive_samples is None else derive_samples,
        pipelines=machine.P,
        clock_hz=machine.arch.clock_hz,
    )
    return CycleResult(
        image=image,
        samples=state.samples,
        rays=int(state.touched.sum()),
        cycles=int(cycles),
        counters=raw,
        elaborated_units=list(machine.elaborated),
        elided_units=list(machine.elided),
        derived=derived,
    )


def elaborate_units(
    backend, everything: bool, structures: tuple[str, ...]
) -> tuple[list[str], list[str]]:
    """The units a scene needs (all of :data:`UNITS` when ``everything``), between the
    machine's front ``structures`` and its pixel bus; and the units elided."""
    be, mode = backend, backend.mode
    needs = {
        "interp": True,
        "gradient": be.need_grad,
        "classify": mode in ("composite", "iso"),
        "shade": be.scene.lit,
        "composite": True,
        "crop": be.scene.crop is not None or bool(be.scene.cut_planes),
    }
    if everything:
        needs = dict.fromkeys(needs, True)
    units = [*structures] + [u for u in UNITS if needs[u]] + ["pixel_bus"]
    return units, [u for u in UNITS if not needs[u]]
