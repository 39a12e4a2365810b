"""What the host writes for one vg500 frame, and the SDRAM image it loads.

# Ref: rtl/frame.py (the pipelines' host writes: geometry, view, tables); architectures.md
#      section 3 (the VLI driver computes the view, shear and tables; the volume is
#      written once into the SDRAM modules in the two-level mini-block layout).

The pipelines of the vg500 top are the Cube-4 top's, so their loads and registers are
:func:`rtl.frame.prepare`'s for the same frame on the same datapath; the vg500 adds the
devices' contents (``layout`` of :mod:`models.machines.volumepro.memory`, the host's
write) and two sizes of the hardware: the SDRAM timing (the arch's ``[memory]``, the
datasheet's) and the slab buffer's capacity (``[buffers] slab_buffer_entries``).  What the
top does not render yet is refused naming the key.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.memory import parse_memory
from models.frame import Frame
from models.machines.volumepro.memory import layout
from rtl.frame import FrameProgram, prepare
from rtl.vg500.front_end import MODULES
from rtl.vg500.sdram_ctrl import SdramTiming

__all__ = ["Vg500Program", "prepare_vg500", "is_vg500"]


def is_vg500(arch) -> bool:
    """Whether ``arch`` is a machine the vg500 top renders (shear-warp VolumePro family,
    four pipelines and SDR modules, the mini-block skew; the family's
    ``models.machines.volumepro.machine.vg500_shaped``, which declares the rung, asks the
    same)."""
    return (
        arch.family == "volumepro"
        and arch.order == "shear-warp"
        and arch.pipelines == MODULES
        and arch.memory.get("modules", MODULES) == MODULES
        and arch.memory.get("skew", "miniblock") == "miniblock"
    )


@dataclass
class Vg500Program:
    """The pipelines' program, the devices' words and the hardware sizes."""

    inner: FrameProgram
    timing: SdramTiming
    slab_entries: int
    rows: int  # device rows per bank the volume uses
    device_words: list[list[int]]  # per module, (bank rows + row) 512 + column


def _refuse(message, key, allowed, source=None):
    return InputError(message, source=source, key=key, allowed=allowed)


def prepare_vg500(frame: Frame) -> Vg500Program:
    """The host's writes of ``frame`` on the vg500 top (refusals name their key)."""
    arch, scene = frame.arch, frame.scene
    if not is_vg500(arch):
        raise NotAvailableError(
            f"the vg500 top renders the four-module shear-warp VolumePro; {arch.name} is not one",
            key="--arch",
            allowed="volumepro500",
        )
    if scene.render.supersampling != 1.0:
        raise _refuse(
            "the vg500 top's pipelines sample once per slice, on the slice (Cube-4's slots: "
            "z supersampling needs sample planes between slices, not in it)",
            "render.supersampling",
            "1",
        )
    memory = parse_memory(arch.memory, source=arch.source)
    timing = SdramTiming.of(memory.sdram)
    # The pipelines are Cube-4's: the same loads, on the same datapath (its shader's
    # method: the VolumePro 500's reflectance maps, which the host computes and loads).
    inner_arch = dataclasses.replace(arch, order="slice-parallel")
    program = prepare(dataclasses.replace(frame, arch=inner_arch))
    n_b = program.registers["n_b"]
    if -(-n_b // 2) < MODULES:
        raise _refuse(
            f"{n_b} voxels along a beam give fewer mini-blocks than modules",
            "volume",
            f">= {2 * MODULES - 1} voxels along every axis",
        )
    n_max, c = max(arch.max_volume), program.registers["c"]
    entries = arch.buffers.get("slab_buffer_entries") or 8 * n_max * -(-n_max // MODULES)
    if entries < 4 * c * (-(-program.registers["n_a"] // 2) + 1):
        raise _refuse(
            f"a slab buffer of {entries} entries cannot hold a slice of mini-block beams",
            "buffers.slab_buffer_entries",
            f">= {4 * c * (-(-program.registers['n_a'] // 2) + 1)}",
            arch.source,
        )
    raw = program.backend.raw
    rows, words = device_image(raw, memory, timing)
    return Vg500Program(program, timing, int(entries), rows, words)


def device_image(
    raw: np.ndarray, memory, timing: SdramTiming, *, rows: int | None = None
) -> tuple[int, list[list[int]]]:
    """The host's write of ``raw`` into the modules: rows per bank (``rows``, default
    those the volume uses), and per module the words in ``(bank rows + row) columns +
    column`` order."""
    n = max(2, max(raw.shape) + max(raw.shape) % 2)
    z, y, x = np.meshgrid(*(np.arange(s) for s in raw.shape), indexing="ij")
    module, bank, address = layout(memory, n, x, y, z)
    rows = rows or int(address.max()) // timing.columns + 1
    out = np.zeros((MODULES, timing.banks * rows * timing.columns), dtype=np.int64)
    index = (bank * rows + address // timing.columns) * timing.columns + address % timing.columns
    out[module.ravel(), index.ravel()] = raw.ravel()
    return rows, [row.tolist() for row in out]
