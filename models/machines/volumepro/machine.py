"""The VolumePro family (``shear-warp``: ``volumepro500``, ``em-cube``; ``shear-image``:
``volumepro1000``) as a :class:`Machine`.

# Ref: architectures.md sections 3-5 (EM-Cube, VolumePro 500, VolumePro 1000).
"""

from __future__ import annotations

from typing import Any

from models.frame import Frame
from models.machines import Machine
from models.machines.volumepro import silicon
from models.machines.volumepro.cycle import SlabFaults, SlabMachine
from models.machines.volumepro.slab_timing import SlabBuffers
from models.machines.volumepro.transaction import SlabTransaction
from models.machines.volumepro.vp1000_transaction import Vp1000Transaction


def cycle(backend, *, faults, trace, progress, steady_state=False):
    """One frame (with ``steady_state``, two back to back) on :class:`SlabMachine`."""
    machine = SlabMachine(backend, faults=faults, trace=trace, steady_state=steady_state)
    return machine.run(progress)


def transaction(frame: Frame, **options: Any) -> SlabTransaction:
    """The slab machines' event model; machines that skip beams (early ray termination,
    space leaping: VolumePro 1000) read the volume, transfer and the rays' ends."""
    if frame.arch.early_termination or frame.arch.space_leaping:
        return Vp1000Transaction(frame, **options)
    return SlabTransaction(frame, **options)


def vg500_shaped(arch) -> bool:
    """Whether the vg500 RTL top (rtl/vg500) renders ``arch``: a shear-warp machine of
    four SDRAM modules and pipelines with the mini-block skew (VolumePro 500, EM-Cube).
    The same test as ``rtl.vg500.frame.is_vg500``, which this package may not import
    (layers: the RTL sits above the machines); tests/rtl/test_vg500_top.py checks that
    the two agree."""
    return (
        arch.order == "shear-warp"
        and arch.pipelines == 4
        and arch.memory.get("modules", 4) == 4
        and arch.memory.get("skew", "miniblock") == "miniblock"
    )


MACHINE = Machine(
    name="volumepro",
    orders=("shear-warp", "shear-image"),
    cycle=cycle,
    transaction=transaction,
    faults_type=SlabFaults,
    steady_state=True,
    package="models.machines.volumepro",
    silicon=silicon.silicon,
    accesses=silicon.accesses,
    buffers=SlabBuffers,
    skew_memory=True,
    rtl_top="rtl.vg500.top",
    rtl_archs=vg500_shaped,
)
