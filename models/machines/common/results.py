"""What every cycle machine shares: its units, its result, buffer tables, elaboration.

# Ref: docs/cycle.md (timing rules, counters, "model only what the scene requires");
#      architectures.md section 9.2 (buffer sizes [I]).

One copy for the Cube-4 machine, the VolumePro slab machine, VIZARD II and the
transaction models that check the same buffers; no machine is named here (the rules of one
family live in its package, e.g. :mod:`models.machines.cube4.timing`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.models import integer, validate
from hwsim.engine import Counters, DrainFifo
from hwsim.engine.metrics import derive
from hwsim.spec.arch import ArchConfig
from models.datapath import units_needed
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import crop as crop_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units import shade as shade_unit

__all__ = [
    "UNITS",
    "CycleResult",
    "Entries",
    "buffer_table",
    "publish_pixel_bus",
    "frame_result",
    "counted_result",
    "elaborate_units",
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


#: A buffer's capacity in entries (a family's ``[buffers]`` model declares its keys as
#: ``Entries | None``: None takes the size its machine derives from ``[limits]``).
Entries = integer(0, 10**8)


def buffer_table(
    arch: ArchConfig, model: type, defaults: dict[str, int], needs: dict[str, int]
) -> dict[str, int]:
    """The ``[buffers]`` table as the family's ``model`` declares it (checked when the file
    was loaded, :func:`models.machines.check_tables`; again here for a config built in
    code), absent keys taking ``defaults``, checked against what this volume ``needs``."""
    given = validate(arch.buffers, model, arch.source, prefix="buffers")
    out = {key: getattr(given, key) for key in defaults}
    out = {key: defaults[key] if value is None else value for key, value in out.items()}
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
    machine,
    image: np.ndarray,
    state,
    cycles: int,
    *,
    latency: int,
    samples: int | None = None,
    derive_samples: int | None = None,
) -> CycleResult:
    """A frame's :class:`CycleResult` from a machine (``counters``, ``P``, ``arch``,
    ``elaborated``, ``elided``) and its back end's final state, with the counters every
    machine publishes (``pipeline.latency_cycles``, ``frame.cycles``, ``frame.samples``).
    ``samples`` is the frame's sample count when the back end composited fewer (VIZARD
    II: leaped and terminated samples are the frame's too, as on the other rungs; default:
    the composited samples); derived metrics per ``derive_samples`` samples (default:
    ``samples``)."""
    samples = state.samples if samples is None else int(samples)
    machine.counters.set("pipeline.latency_cycles", latency)
    machine.counters.set("frame.cycles", cycles)
    machine.counters.set("frame.samples", samples)
    raw = machine.counters.as_dict()
    derived = derive(
        raw,
        cycles=cycles,
        samples=samples if derive_samples is None else derive_samples,
        pipelines=machine.P,
        clock_hz=machine.arch.clock_hz,
    )
    return CycleResult(
        image=image,
        samples=samples,
        rays=int(state.touched.sum()),
        cycles=int(cycles),
        counters=raw,
        elaborated_units=list(machine.elaborated),
        elided_units=list(machine.elided),
        derived=derived,
    )


def counted_result(machine, image: np.ndarray, samples: int, rays: int, cycles: int) -> CycleResult:
    """A frame's :class:`CycleResult` from a machine (``counters``, ``P``, ``arch``,
    ``elaborated``, ``elided``) whose pixels came from elsewhere than a back end's state
    (Cube-1, Cube-3, VOGUE: the shared back end on what their memory delivered), with
    ``frame.cycles`` and ``frame.samples`` set and the derived metrics."""
    machine.counters.set("frame.cycles", cycles)
    machine.counters.set("frame.samples", samples)
    raw = machine.counters.as_dict()
    derived = derive(
        raw, cycles=cycles, samples=samples, pipelines=machine.P, clock_hz=machine.arch.clock_hz
    )
    return CycleResult(
        image=image,
        samples=samples,
        rays=rays,
        cycles=int(cycles),
        counters=raw,
        elaborated_units=list(machine.elaborated),
        elided_units=list(machine.elided),
        derived=derived,
    )


def elaborate_units(backend, structures: tuple[str, ...]) -> tuple[list[str], list[str]]:
    """The units a scene needs (all of :data:`UNITS` when the back end exercises unused
    units), between the machine's front ``structures`` and its pixel bus; and the units
    elided."""
    needs = units_needed(backend.scene, backend.transfer.modulates)
    if backend.exercise_unused:
        needs = dict.fromkeys(needs, True)
    units = [*structures] + [u for u in UNITS if needs[u]] + ["pixel_bus"]
    return units, [u for u in UNITS if not needs[u]]
