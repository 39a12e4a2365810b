"""The VolumePro family (``shear-warp``: ``volumepro500``, ``em-cube``; ``shear-image``:
``volumepro1000``) as a :class:`Machine`.

# Ref: architectures.md sections 3-5 (EM-Cube, VolumePro 500, VolumePro 1000).
"""

from __future__ import annotations

from typing import Any

from models.machines import Machine
from models.machines.volumepro.cycle import SlabFaults, SlabMachine
from models.machines.volumepro.transaction import SlabTransaction
from models.machines.volumepro.vp1000_transaction import Vp1000Transaction


def cycle(backend, plan, *, faults, elaborate_all, trace, progress, steady_state=False):
    """One frame (with ``steady_state``, two back to back) on :class:`SlabMachine`."""
    extra = {"steady_state": True} if steady_state else {}
    machine = SlabMachine(
        backend, plan, faults=faults, elaborate_all=elaborate_all, trace=trace, **extra
    )
    return machine.run(progress)


def transaction(
    scene, arch, plan, *, volume=None, transfer=None, stopped=None, datapath=None, **options: Any
) -> SlabTransaction:
    """The slab machines' event model; machines that skip beams (early ray termination,
    space leaping: VolumePro 1000) read the volume, transfer and the rays' ends."""
    if arch.early_termination or arch.space_leaping:
        frame = {"volume": volume, "transfer": transfer, "stopped": stopped, "datapath": datapath}
        return Vp1000Transaction(scene, arch, plan, **frame, **options)
    return SlabTransaction(scene, arch, plan, **options)


MACHINE = Machine(
    name="volumepro",
    orders=("shear-warp", "shear-image"),
    cycle=cycle,
    transaction=transaction,
    faults_type=SlabFaults,
    steady_state=True,
    package="models.machines.volumepro",
)
