"""VIZARD II's silicon for the energy and area model: its block cache, ray queue and pixel
FIFO, and a frame's memory actions.

# Ref: architectures.md section 5 (image-order ray casting, ray queueing, VoxelCache,
#      SDRAM volume memory [V]); models/machines/vizard2/config.py (capacities [I]);
#      docs/energy.md.
"""

from __future__ import annotations

from collections.abc import Mapping

from hwsim.spec.arch import ArchConfig
from models.datapath import Datapath
from models.machines.common.silicon import Access, Silicon, Storage, counter_sum
from models.machines.vizard2.config import BLOCK, memory_of, parse_buffers

__all__ = ["accesses", "silicon"]

#: Words a lookup reads from a cache line: a sample's eight voxels (each with its
#: gradient-table index).
_LOOKUP_WORDS = 8


def silicon(arch: ArchConfig, dp: Datapath) -> Silicon:
    """The block cache (lines of one ``BLOCK^3`` block), the ray queue (a ray's position,
    step and accumulator per entry) and the pixel FIFO."""
    buffers, word = parse_buffers(arch), memory_of(arch).sdram.word_bits
    acc = 4 * (dp.composite.acc_frac_bits + 1)
    return Silicon(
        storage=(
            Storage("block_cache", buffers.cache_lines * BLOCK**3, word),
            Storage("ray_queue", buffers.ray_queue_entries, acc + 3 * 32),
            Storage("pixel_fifo", buffers.pixel_fifo_entries, 4 * dp.composite.output_bits),
        ),
        lerps=7,  # samples anywhere along the ray: trilinear
    )


def accesses(
    counters: Mapping[str, int], arch: ArchConfig, dp: Datapath, units: list[str]
) -> list[Access]:
    """SDRAM bursts, activations and refreshes as counted; a cache lookup reads a sample's
    eight words, a fill writes a whole line; each issued sample reads and writes its ray's
    queue entry; every pixel enters and leaves the FIFO."""
    memory = memory_of(arch).sdram
    word = memory.word_bits
    bursts = counter_sum(counters, "memory.bursts")
    samples = counter_sum(counters, "frame.issued_samples", "frame.samples")
    pixels = counter_sum(counters, "pixel_bus.pixels")
    ray_bits, out_bits = 4 * (dp.composite.acc_frac_bits + 1) + 3 * 32, 4 * dp.composite.output_bits
    return [
        Access("dram", "read", bursts * memory.burst_length, word),
        Access("dram", "activate", counter_sum(counters, "memory.activates")),
        Access("dram", "refresh", counter_sum(counters, "memory.refreshes")),
        Access("block_cache", "read", counter_sum(counters, "cache.lookups"), _LOOKUP_WORDS * word),
        Access("block_cache", "write", counter_sum(counters, "cache.fills"), BLOCK**3 * word),
        Access("ray_queue", "read", samples, ray_bits),
        Access("ray_queue", "write", samples, ray_bits),
        Access("pixel_fifo", "write", pixels, out_bits),
        Access("pixel_fifo", "read", pixels, out_bits),
    ]
