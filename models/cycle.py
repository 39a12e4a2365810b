"""The ``cycle`` rung: exact cycles from the modelled hardware of an architecture.

# Ref: design.md section 3 (cycle rung: bit-identical to functional, exact cycle count,
#      per-unit busy/stall counters, optional VCD); architectures.md section 1 (Cube-4).

The machine is the family the registry (:mod:`models.machines`) holds for the
architecture's processing order: the Cube-4 family (``slice-parallel``), the VolumePro
family (``shear-warp``, ``shear-image``) and VIZARD II (``ray``).  An order no family
models at this rung raises :class:`~hwsim.core.errors.NotAvailableError` naming those that are.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.engine import VcdTrace
from hwsim.spec.arch import ArchConfig
from models.backend import Backend
from models.frame import Frame
from models.machines import families, machine_for
from models.machines.common.results import CycleResult

__all__ = ["render_cycle", "has_cycle_model", "steady_state_orders", "CycleResult"]


def has_cycle_model(arch: ArchConfig) -> bool:
    """Whether the cycle rung models ``arch`` (its machine family)."""
    try:
        return machine_for(arch).cycle is not None
    except NotAvailableError:
        return False


def steady_state_orders() -> tuple[str, ...]:
    """Orders whose machine times back-to-back frames (``steady_state``)."""
    return tuple(o for m in families() if m.steady_state for o in m.orders)


def render_cycle(
    frame: Frame,
    *,
    faults: object | None = None,
    elaborate_all: bool = False,
    trace: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    steady_state: bool = False,
    compiled: bool = True,
) -> CycleResult:
    """Render ``frame`` on its architecture's modelled hardware.

    Parameters
    ----------
    faults : the family's ``faults_type``, optional
        Structures to break (fault-injection tests).
    elaborate_all : bool
        Simulate every unit, even those the scene does not use, discarding what they
        compute (a fixed pipeline with disabled units): the elision check.
    trace : path, optional
        Write a VCD of memory reads, interpolator inputs and the pixel bus there.
    steady_state : bool
        VolumePro family: also time a second frame back to back and report the cycles
        between the two frames' ends (``frame.period_cycles``: the continuous frame rate).
    compiled : bool
        Let a machine run its composite stage in a compiled kernel where it has one
        (Cube-4: :mod:`models.machines.cube4.slice_kernel`); False: the vectorised unit
        chain everywhere (the same bits, slower).
    """
    arch = frame.arch
    machine = machine_for(arch, "cycle")
    if steady_state and not machine.steady_state:
        raise InputError(
            f"{arch.name} ({arch.order} order) times single frames only",
            key="steady_state",
            allowed=f"a machine of order {', '.join(steady_state_orders())}",
        )
    if faults is not None and not isinstance(faults, machine.faults_type):
        raise TypeError(f"{arch.name} takes {machine.faults_type.__name__} faults")
    backend = Backend(frame, exercise_unused=elaborate_all, compiled=compiled)
    vcd = VcdTrace() if trace is not None else None
    result = machine.cycle(
        backend, faults=faults, trace=vcd, progress=progress, steady_state=steady_state
    )
    if vcd is not None:
        vcd.write(trace)
    return result
