"""Cube-4's silicon for the energy and area model: its buffers and a frame's memory actions.

# Ref: architectures.md sections 1.2-1.3 and 9.2 (P skewed DRAM modules read one voxel per
#      clock; per pipeline a beam FIFO of n/P and two slice FIFOs of n^2/P voxels; the
#      compositing buffer; the pixel FIFO); docs/energy.md.
"""

from __future__ import annotations

from collections.abc import Mapping

from hwsim.spec.arch import ArchConfig
from models.datapath import Datapath
from models.machines.common.silicon import Access, Silicon, Storage, counter_sum
from models.machines.cube4.frame import cube4_buffers
from models.machines.cube4.memory import WORD_BYTES

__all__ = ["accesses", "silicon"]


def silicon(arch: ArchConfig, dp: Datapath) -> Silicon:
    """Per pipeline a beam FIFO, two slice FIFOs and a compositing buffer of one slice's
    rays (``n^2 / P`` accumulators); one pixel FIFO; all sized for ``limits.max_volume``."""
    n = max(arch.max_volume)
    C = -(-n // arch.pipelines)
    caps = cube4_buffers(arch, C, n * C)
    P, v = arch.pipelines, dp.voxel_bits
    acc = 4 * (dp.composite.acc_frac_bits + 1)
    return Silicon(
        storage=(
            Storage("beam_fifo", caps["beam_fifo_entries"], v, P),
            Storage("slice_fifo", caps["slice_fifo_entries"], v, 2 * P),
            Storage("compositing_buffer", n * C, acc, P),
            Storage("pixel_fifo", caps["pixel_fifo_entries"], 4 * dp.composite.output_bits),
        ),
        lerps=3,  # samples lie on voxel slices: a bilinear
    )


def accesses(
    counters: Mapping[str, int], arch: ArchConfig, dp: Datapath, units: list[str]
) -> list[Access]:
    """Every voxel read from its module passes the beam FIFO (and, when gradients need
    the neighbouring slices, both slice FIFOs): a write and a read each; every sample
    reads and writes its ray's accumulator; every pixel enters and leaves the FIFO.
    The modules are read in page order (no activations counted)."""
    reads = counter_sum(counters, "memory.module[].reads", "memory.reads")
    samples = counter_sum(counters, "frame.samples")
    pixels = counter_sum(counters, "pixel_bus.pixels")
    v, acc = dp.voxel_bits, 4 * (dp.composite.acc_frac_bits + 1)
    out = [
        Access("dram", "read", reads, 8 * WORD_BYTES),
        Access("beam_fifo", "write", reads, v),
        Access("beam_fifo", "read", reads, v),
        Access("compositing_buffer", "read", samples, acc),
        Access("compositing_buffer", "write", samples, acc),
        Access("pixel_fifo", "write", pixels, 4 * dp.composite.output_bits),
        Access("pixel_fifo", "read", pixels, 4 * dp.composite.output_bits),
    ]
    if "gradient" in units:
        out += [Access("slice_fifo", kind, 2 * reads, v) for kind in ("write", "read")]
    return out
