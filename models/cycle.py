"""The ``cycle`` rung: exact cycles from the modelled hardware of an architecture.

# Ref: design.md section 3 (cycle rung: bit-identical to functional, exact cycle count,
#      per-unit busy/stall counters, optional VCD); architectures.md section 1 (Cube-4).

Modelled: the Cube-4 family (processing order ``slice-parallel``: ``cube4``,
``cube4-teramac`` and user variants; :class:`models.arch.cube4.Cube4Machine`) and the
VolumePro family (``shear-warp``: ``volumepro500``, ``em-cube``; ``shear-image``:
``volumepro1000``; :class:`models.arch.volumepro.SlabMachine`) and VIZARD II (``ray``:
:mod:`models.arch.vizard2`).  Other machines raise
:class:`~hwsim.errors.NotAvailableError` naming what is.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hwsim.arch import ArchConfig
from hwsim.engine import VcdTrace
from hwsim.errors import InputError, NotAvailableError
from hwsim.golden.positions import SamplePlan
from hwsim.scene import Scene
from hwsim.transfer import TransferFunction
from hwsim.volumes.volume import Volume
from models.arch.cube4 import Cube4Machine, CycleResult, Faults
from models.arch.volumepro import SlabMachine
from models.backend import Backend
from models.datapath import Datapath

__all__ = ["render_cycle", "CYCLE_ORDERS", "STEADY_STATE_ORDERS", "Faults", "CycleResult"]

#: The machine model of each processing order the cycle rung models.
MACHINES = {
    "slice-parallel": Cube4Machine,
    "shear-warp": SlabMachine,
    "shear-image": SlabMachine,
}
#: Processing orders the cycle rung models.
CYCLE_ORDERS = (*MACHINES, "ray")
#: Orders whose machine times back-to-back frames (``steady_state``).
STEADY_STATE_ORDERS = ("shear-warp", "shear-image")


def render_cycle(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    arch: ArchConfig,
    plan: SamplePlan,
    *,
    faults: Faults | None = None,
    elaborate_all: bool = False,
    trace: str | Path | None = None,
    datapath: Datapath | None = None,
    progress: Callable[[int, int], None] | None = None,
    steady_state: bool = False,
) -> CycleResult:
    """Render one frame on ``arch``'s modelled hardware.

    Parameters
    ----------
    faults : Faults, optional
        Structures to break (fault-injection tests).
    elaborate_all : bool
        Simulate every unit, even those the scene does not use, discarding what they
        compute (a fixed pipeline with disabled units): the elision check.
    trace : path, optional
        Write a VCD of memory reads, interpolator inputs and the pixel bus there.
    steady_state : bool
        VolumePro family: also time a second frame back to back and report the cycles
        between the two frames' ends (``frame.period_cycles``: the continuous frame rate).
    """
    if steady_state and arch.order not in STEADY_STATE_ORDERS:
        raise InputError(
            f"{arch.name} ({arch.order} order) times single frames only",
            key="steady_state",
            allowed=f"a machine of order {', '.join(STEADY_STATE_ORDERS)}",
        )
    if arch.order == "ray":  # VIZARD II (docs/cycle.md)
        from models.arch.vizard2 import render_vizard2

        return render_vizard2(
            scene, volume, transfer, arch, plan, faults, elaborate_all, trace, datapath, progress
        )
    if arch.order not in CYCLE_ORDERS:
        raise NotAvailableError(
            f"{arch.name} ({arch.order} order) is not modelled at cycle fidelity",
            key="--arch",
            allowed=f"a machine of order {', '.join(CYCLE_ORDERS)}",
        )
    if datapath is None:
        datapath = Datapath.for_volume(arch, volume)
    backend = Backend(scene, volume, transfer, arch, plan, datapath, exercise_unused=elaborate_all)
    vcd = VcdTrace() if trace is not None else None
    extra = {"steady_state": True} if steady_state else {}
    machine = MACHINES[arch.order](
        backend, plan, faults=faults, elaborate_all=elaborate_all, trace=vcd, **extra
    )
    result = machine.run(progress)
    if vcd is not None:
        vcd.write(trace)
    return result
