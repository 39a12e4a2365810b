"""VIZARD II machine parameters: the ``[buffers]`` model, ``[memory]`` and fault injection.

# Ref: architectures.md section 5 (ray queueing, Doggett ISCAS 2000 [V]; VoxelCache's
#      4^3-voxel blocks [V]); the sizes below are [I] (not published).
"""

from __future__ import annotations

from dataclasses import dataclass

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, count, integer, validate
from hwsim.memory import MemoryConfig, parse_memory
from hwsim.spec.arch import ArchConfig
from models.frame import Frame
from models.machines.common.results import UNITS, Entries
from models.machines.common.sections import refuse_sections

__all__ = [
    "BLOCK",
    "FEEDBACK",
    "FILL_WRITE",
    "LOOKUP_LATENCY",
    "VizardFaults",
    "VizardBuffers",
    "check_arch",
    "check_frame",
    "parse_buffers",
    "memory_of",
]

#: Block edge in voxels (VoxelCache's 4^3 blocks [V]).
BLOCK = 4
LOOKUP_LATENCY = 1  # cache tag check [I] (docs/cycle.md rule 3)
FILL_WRITE = 1  # last beat to line written [I] (rule 2)
#: Issue of a sample to its opacity at the compositor: lookup + every unit (rule 3).
FEEDBACK = LOOKUP_LATENCY + sum(u.LATENCY for u in UNITS.values())


@dataclass(frozen=True, kw_only=True)
class VizardFaults:
    """Fault injection (tests): each field breaks one modelled structure.

    ``stuck_word = (address, value)``: every voxel of SDRAM value word ``address`` reads
    ``value``; ``stuck_bank = (bank, value)``: every voxel value in SDRAM bank ``bank``
    reads ``value`` (its gradient-table words read 0); ``corrupt_line = (line, mask)``:
    voxel values written into cache line ``line`` are XORed with ``mask``;
    ``dropped_fill = k``: the ``k``-th cache fill updates the tag but writes no data;
    ``ray_queue_entries``: the ray queue's depth (0: the ray generator can place no ray);
    ``pixel_fifo_depth``: the pixel FIFO's depth.
    """

    stuck_word: tuple[int, int] | None = None
    stuck_bank: tuple[int, int] | None = None
    corrupt_line: tuple[int, int] | None = None
    dropped_fill: int | None = None
    ray_queue_entries: int | None = None
    pixel_fifo_depth: int | None = None


class VizardBuffers(Schema):
    """``[buffers]``: the on-chip structures (sizes [I]): the ray tile (rays of one packet,
    image rows x columns) and queue (rays in flight), the block cache's sets (z, y, x:
    lines of one 4^3 block each) and the pixel FIFO."""

    ray_tile: tuple[count(), count()] = (8, 8)
    ray_queue_entries: Entries = 64
    cache_sets: tuple[integer(2), integer(2), integer(2)] = (4, 4, 4)
    pixel_fifo_entries: Entries = 64

    @property
    def cache_lines(self) -> int:
        z, y, x = self.cache_sets
        return z * y * x


def check_frame(frame: Frame) -> None:
    """Refuse what VIZARD II cannot render (every rung of the machine asks here): plans
    that are not cast from the image plane, gradients other than its table of
    pre-computed voxel gradients, sections."""
    arch, plan, datapath = frame.arch, frame.plan, frame.datapath
    refuse_sections(arch, "VIZARD II")
    if plan.kind != "ray":
        raise InputError(
            "VIZARD II casts rays from the image plane",
            source=arch.source,
            key="pipeline.order",
            allowed="ray",
        )
    if datapath.gradient.source != "voxel":
        raise InputError(
            "VIZARD II interpolates a table of pre-computed voxel gradients",
            source=arch.source,
            key="formats.gradient.source",
            allowed="voxel",
        )


def parse_buffers(arch: ArchConfig) -> VizardBuffers:
    """``arch.buffers`` as :class:`VizardBuffers` (checked when the file was loaded; again
    here for a config built in code)."""
    return validate(arch.buffers, VizardBuffers, arch.source, prefix="buffers")


def check_arch(arch: ArchConfig) -> None:
    """The rules of a VIZARD II file across its tables, asked when it is loaded
    (:attr:`models.machines.Machine.check_arch`)."""
    memory_of(arch)


def memory_of(arch: ArchConfig) -> MemoryConfig:
    """The ``[memory]`` table (one channel: ``modules = 1``, blocks stored one after
    another: ``skew = "block"``)."""
    memory = parse_memory(arch.memory, source=arch.source)
    if memory.skew != "block":
        raise InputError(
            f"the VIZARD II memory stores 4^3 blocks one after another, not {memory.skew!r}",
            source=arch.source,
            key="memory.skew",
            allowed="block",
        )
    if memory.modules != 1:
        raise InputError(
            f"the VIZARD II model has one memory channel, not {memory.modules}",
            source=arch.source,
            key="memory.modules",
            allowed="1",
        )
    return memory
