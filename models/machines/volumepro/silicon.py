"""The VolumePro family's silicon for the energy and area model: buffers and memory actions.

# Ref: architectures.md sections 3 and 9.1-9.3 (SDRAM modules read in mini-block bursts,
#      slab buffers of four mini-block slabs, beam FIFOs, the compositing buffer, the
#      pixel FIFO); models/machines/volumepro/slab_timing.py (their capacities);
#      docs/energy.md.
"""

from __future__ import annotations

from collections.abc import Mapping

from hwsim.memory import parse_memory
from hwsim.spec.arch import ArchConfig
from models.datapath import Datapath
from models.machines.common.silicon import Access, Silicon, Storage, counter_sum
from models.machines.volumepro.slab_timing import slab_buffers

__all__ = ["accesses", "silicon"]


def silicon(arch: ArchConfig, dp: Datapath) -> Silicon:
    """Per pipeline a slab buffer, a beam FIFO and a compositing buffer of one slice's
    rays; one pixel FIFO; sized for ``limits.max_volume``."""
    n = max(arch.max_volume)
    C = -(-n // arch.pipelines)
    caps = slab_buffers(arch, C)
    P, word = arch.pipelines, parse_memory(arch.memory, source=arch.source).sdram.word_bits
    acc = 4 * (dp.composite.acc_frac_bits + 1)
    return Silicon(
        storage=(
            Storage("slab_buffer", caps["slab_buffer_entries"], word, P),
            Storage("beam_fifo", caps["beam_fifo_entries"], dp.voxel_bits, P),
            Storage("compositing_buffer", n * C, acc, P),
            Storage("pixel_fifo", caps["pixel_fifo_entries"], 4 * dp.composite.output_bits),
        ),
        lerps=7,  # sample slices between voxel slices: trilinear
    )


def accesses(
    counters: Mapping[str, int], arch: ArchConfig, dp: Datapath, units: list[str]
) -> list[Access]:
    """SDRAM bursts (``burst_length`` words each), activations and refreshes as the memory
    model counted them; every word read is written into its slab buffer and read out of
    it into the beams once (the ring and beam FIFOs reuse it); every sample reads and
    writes its ray's accumulator; every pixel enters and leaves the FIFO."""
    memory = parse_memory(arch.memory, source=arch.source).sdram
    bursts = counter_sum(counters, "memory.sdram.bursts")
    words = bursts * memory.burst_length
    samples = counter_sum(counters, "frame.samples")
    pixels = counter_sum(counters, "pixel_bus.pixels")
    acc, out_bits = 4 * (dp.composite.acc_frac_bits + 1), 4 * dp.composite.output_bits
    return [
        Access("dram", "read", words, memory.word_bits),
        Access("dram", "activate", counter_sum(counters, "memory.sdram.activates")),
        Access("dram", "refresh", counter_sum(counters, "memory.sdram.refreshes")),
        Access("slab_buffer", "write", words, memory.word_bits),
        Access("slab_buffer", "read", words, memory.word_bits),
        Access("beam_fifo", "write", words, dp.voxel_bits),
        Access("beam_fifo", "read", words, dp.voxel_bits),
        Access("compositing_buffer", "read", samples, acc),
        Access("compositing_buffer", "write", samples, acc),
        Access("pixel_fifo", "write", pixels, out_bits),
        Access("pixel_fifo", "read", pixels, out_bits),
    ]
