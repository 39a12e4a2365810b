"""VIZARD II machine parameters: the ``[buffers]`` table, ``[memory]`` and fault injection.

# Ref: architectures.md section 5 (ray queueing, Doggett ISCAS 2000 [V]; VoxelCache's
#      4^3-voxel blocks [V]); the sizes below are [I] (not published).
"""

from __future__ import annotations

from dataclasses import dataclass

from hwsim.core.errors import InputError
from hwsim.memory import MemoryConfig, parse_memory
from hwsim.spec.arch import ArchConfig
from models.frame import Frame
from models.machines.common.results import UNITS, check_buffer_keys
from models.machines.common.sections import refuse_sections

__all__ = [
    "BLOCK",
    "FEEDBACK",
    "FILL_WRITE",
    "LOOKUP_LATENCY",
    "VizardFaults",
    "VizardBuffers",
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


@dataclass(frozen=True)
class VizardBuffers:
    """On-chip structures: ray tile and queue, cache geometry, pixel FIFO."""

    ray_tile: tuple[int, int]
    ray_queue_entries: int
    cache_sets: tuple[int, int, int]
    pixel_fifo_entries: int

    @property
    def cache_lines(self) -> int:
        z, y, x = self.cache_sets
        return z * y * x


_DEFAULTS = {
    "ray_tile": [8, 8],  # rays of one packet, image rows x columns [I]
    "ray_queue_entries": 64,  # rays in flight at once [I]
    "cache_sets": [4, 4, 4],  # 64 lines of one 4^3 block each [I]
    "pixel_fifo_entries": 64,  # [I]
}


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
    """Validate ``arch.buffers`` (missing keys: the defaults above)."""
    check_buffer_keys(arch, _DEFAULTS)
    table = {**_DEFAULTS, **arch.buffers}

    def ints(key: str, count: int, lo: int) -> list[int]:
        value = table[key]
        values = value if isinstance(value, list) else [value]
        ok = len(values) == count and all(
            isinstance(v, int) and not isinstance(v, bool) and v >= lo for v in values
        )
        if not ok:
            shape = "an integer" if count == 1 else f"a list of {count} integers"
            raise InputError(
                f"invalid {value!r}",
                source=arch.source,
                key=f"buffers.{key}",
                allowed=f"{shape} >= {lo}",
            )
        return values

    return VizardBuffers(
        ray_tile=tuple(ints("ray_tile", 2, 1)),  # type: ignore[arg-type]
        ray_queue_entries=ints("ray_queue_entries", 1, 0)[0],
        cache_sets=tuple(ints("cache_sets", 3, 2)),  # type: ignore[arg-type]
        pixel_fifo_entries=ints("pixel_fifo_entries", 1, 0)[0],
    )


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
