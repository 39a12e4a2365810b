"""One Cube-4 frame as a host driver sets it up: the scenes the machine refuses, the slice
axes and direction, clocks per beam and slice, buffer capacities and the geometry unit.

The cycle model (:class:`~models.machines.cube4.cycle.Cube4Machine`) extends it with the
memory, datapath and timing; the RTL rung's host (``rtl/frame.py``) uses it alone to write
the registers a driver would, so the RTL never imports the cycle model.

# Ref: architectures.md sections 1.1-1.3 (slice order, beams, P pipelines).
"""

from __future__ import annotations

from hwsim.core.errors import InputError
from hwsim.core.models import Schema
from hwsim.spec.arch import ArchConfig
from models.backend import Backend
from models.frame import Frame
from models.machines.common.results import Entries, buffer_table
from models.machines.common.sections import refuse_sections
from models.machines.common.slice_order import SliceOrderMachine

__all__ = ["Cube4Buffers", "Cube4Frame", "check_cube4_frame", "cube4_buffers"]


class Cube4Buffers(Schema):
    """``[buffers]`` of a Cube-4 machine: entries per pipeline; absent, sized for
    ``limits.max_volume`` (:func:`cube4_buffers`)."""

    beam_fifo_entries: Entries | None = None
    slice_fifo_entries: Entries | None = None
    pixel_fifo_entries: Entries | None = None


def check_cube4_frame(frame: Frame) -> None:
    """Refuse what no Cube-4 renders (every rung of the family asks here): more or fewer
    than one sample per slice, gradients from voxels instead of samples, sections."""
    arch = frame.arch
    refuse_sections(arch, "Cube-4")
    if frame.scene.render.supersampling != 1.0:
        raise InputError(
            "the Cube-4 model samples once per slice",
            source=arch.source,
            key="render.supersampling",
            allowed="1",
        )
    if frame.datapath.gradient.source != "sample":
        raise InputError(
            "Cube-4 estimates gradients from samples",
            source=arch.source,
            key="formats.gradient.source",
            allowed="sample",
        )


class Cube4Frame(SliceOrderMachine):
    """The frame geometry of ``plan`` on ``backend``'s Cube-4 machine (refused with an
    :class:`~hwsim.core.errors.InputError` where the machine cannot render it)."""

    def __init__(self, backend: Backend) -> None:
        self.be, self.plan, self.dp = backend, backend.plan, backend.dp
        self.arch = arch = backend.arch
        self.P = arch.pipelines
        check_cube4_frame(backend.frame)
        self._slice_geometry(backend.volume.shape)
        self.capacity = cube4_buffers(arch, self.C, self.T)

    def slice_of(self, j: int) -> int:
        """The volume slice read at step ``j`` of the frame."""
        return j if self.forward else self.n_kp - 1 - j


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
    needs = {"beam_fifo_entries": C + 1, "slice_fifo_entries": T}
    return buffer_table(arch, Cube4Buffers, defaults, needs)
