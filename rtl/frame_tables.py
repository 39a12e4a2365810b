"""The host's tables and registers of one frame on the RTL top (:mod:`rtl.frame`): the
voxel memory's words in the Cube-4 skewed layout, the shader's tables (reflectance maps
or Phong's specular table), the gradient, modulation and shading registers, and the
packing of fields into load words and registers.

# Ref: architectures.md section 1 (Cube-4: the host loads the volume and the tables);
#      docs/numerics.md (the formats packed).
"""

from __future__ import annotations

import numpy as np

from models.backend import Backend
from models.datapath import Datapath
from models.units import composite as composite_unit
from models.units import skew
from rtl.top_layouts import LOAD_CORRECTION, LOAD_DIFFUSE_MAP, LOAD_GM, LOAD_LUT, LOAD_SPEC
from rtl.top_pipeline import MAX_LIGHTS

__all__ = [
    "pack_fields",
    "shader_loads",
    "shading_registers",
    "table_loads",
    "voxel_memory_words",
]


def pack_fields(layout, fields: dict[str, int]) -> int:
    """One word of ``layout`` (a ``rtl.top_layouts`` layout) holding ``fields``, each value
    cut to its field's width."""
    word = 0
    for name, value in fields.items():
        f = layout[name]
        width = f.shape.width
        word |= (int(value) & ((1 << width) - 1)) << f.offset
    return word


def voxel_memory_words(raw: np.ndarray, P: int, B: int) -> list[int]:
    """The voxel memory's contents in the Cube-4 skewed layout (``models.units.skew``):
    word ``w`` holds module ``k``'s voxel at its word ``w`` in bits ``k B``."""
    nz, ny, nx = raw.shape
    z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    module = skew.cube4_module(x, y, z, P).ravel()
    word = skew.cube4_address_zyx(z, y, x, raw.shape, P).ravel()
    voxels = np.asarray(raw, dtype=np.int64).ravel()
    fields = np.zeros((nz * ny * -(-nx // P), P), dtype=np.int64)
    fields[word, module] = voxels
    words = [0] * fields.shape[0]
    for k in range(P):  # Python ints: P B may exceed 64 bits
        column = fields[:, k].tolist()
        words = [w | (v << (k * B)) for w, v in zip(words, column, strict=True)]
    return words


def table_loads(scene, transfer, plan, backend: Backend, dp: Datapath):
    """``(loads, lit, modulate)``: the classification LUT and the opacity-correction
    table (for the plan's ``dt``) of a composite, the gradient-magnitude table when the
    scene modulates opacity, the shader's tables when it is lit."""
    loads: list[tuple[int, int, int]] = []
    mode = scene.render.mode
    if mode == "composite":
        lut, c = backend.lut, dp.classify.color_bits
        entry = lut.rgb[:, 0] | lut.rgb[:, 1] << c | lut.rgb[:, 2] << 2 * c | lut.alpha << 3 * c
        loads += [(LOAD_LUT, i, int(e)) for i, e in enumerate(entry)]
        k = float(plan._dt) / backend.ref
        table = composite_unit.correction_table(int(dp.composite.ratio.quantize(k)), dp.composite)
        loads += [(LOAD_CORRECTION, i, int(e)) for i, e in enumerate(table)]
    modulate = mode == "composite" and backend.need_grad and transfer.modulates
    if modulate:
        loads += [(LOAD_GM, i, int(e)) for i, e in enumerate(backend.gm_table)]
    lit = mode == "composite" and scene.lit
    if lit:
        loads += shader_loads(backend.shader)
    return loads, lit, modulate


def shader_loads(shader) -> list[tuple[int, int, int]]:
    """The shader's tables: the reflectance maps (diffuse, specular: one entry per cube
    cell, the lights summed in, ``models.units.shade.setup``) or Phong's specular table."""
    if shader.maps is not None:
        diffuse, specular = shader.maps
        return [(LOAD_DIFFUSE_MAP, i, int(e)) for i, e in enumerate(diffuse)] + [
            (LOAD_SPEC, i, int(e)) for i, e in enumerate(specular)
        ]
    return [(LOAD_SPEC, i, int(e)) for i, e in enumerate(shader.spec)]


def shading_registers(backend: Backend, dp: Datapath, lit: bool, modulate: bool) -> dict:
    """Gradient, modulation and shading registers (zeros where the scene does not use
    them; unused lights have intensity 0, which adds exactly nothing).  A reflectance-map
    shader has only ``ka``: its lights are in the maps."""
    f = dp.shade.normal_frac_bits
    spacing_xyz = np.asarray(backend.volume.spacing, dtype=np.float64)[::-1]
    ratio = np.floor(spacing_xyz.min() / spacing_xyz * 4096 + 0.5).astype(np.int64)
    regs = {
        "lit": int(lit),
        "modulate": int(modulate),
        "gm_scale": int(backend.gm_scale) if modulate else 0,
        "ratio": _fields([int(r) for r in ratio], 13),
        "ka": int(backend.shader.ka) if lit else 0,
    }
    if dp.shade.method != "phong":
        return regs
    regs.update(kd=0, ks=0, light=0, half=0, intensity=0)
    if lit:
        sh = backend.shader
        k = sh.light.shape[0]
        pad = [[0, 0, 0]] * (MAX_LIGHTS - k)
        regs.update(
            kd=sh.kd,
            ks=sh.ks,
            light=_fields([c for v in [*sh.light.tolist(), *pad] for c in v], f + 2),
            half=_fields([c for v in [*sh.half.tolist(), *pad] for c in v], f + 2),
            intensity=_fields([*sh.intensity.tolist(), *[0] * (MAX_LIGHTS - k)], 12),
        )
    return regs


def _fields(values: list[int], width: int) -> int:
    """Two's-complement ``width``-bit fields packed first at bit 0."""
    word = 0
    for i, value in enumerate(values):
        word |= (int(value) & ((1 << width) - 1)) << (i * width)
    return word
