"""One frame to render: what every rung below golden takes.

# Ref: design.md section 3 (the rungs render the same scene, volume and transfer function
#      on one architecture at one set of sample positions).

A :class:`Frame` bundles the scene, the volume, the resolved transfer function, the
architecture, the sample plan and the architecture's datapath for that volume.  The
functional, transaction, cycle and rtl rungs, the back end and the machines' event models
all take one, so "the same frame" is one object rather than six arguments passed in the
same order at every call.
"""

from __future__ import annotations

from dataclasses import dataclass

from hwsim.golden.positions import SamplePlan, make_plan
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import Scene
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes.volume import Volume
from models.datapath import Datapath

__all__ = ["Frame", "frame_of"]


@dataclass(frozen=True)
class Frame:
    """One frame of ``scene`` on ``arch``: build it with :func:`frame_of`."""

    scene: Scene
    volume: Volume
    transfer: TransferFunction
    arch: ArchConfig
    plan: SamplePlan
    datapath: Datapath


def frame_of(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    arch: ArchConfig,
    plan: SamplePlan | None = None,
    *,
    datapath: Datapath | None = None,
) -> Frame:
    """The frame of ``scene`` on ``arch``.

    ``plan`` defaults to the sample positions of ``arch``'s processing order;
    ``datapath`` to ``arch``'s ``[formats]`` for ``volume``'s voxel bits.
    """
    if plan is None:
        plan = make_plan(scene, volume, arch.order)
    if datapath is None:
        datapath = Datapath.for_volume(arch, volume)
    return Frame(scene, volume, transfer, arch, plan, datapath)
