"""Sizes and payload layouts of the Cube-4 pipeline top (:mod:`rtl.top`), shared by the
RTL, the host program (:mod:`rtl.frame`) and the simulator drivers.

# Ref: architectures.md section 9.2 (buffer sizes per pipeline); docs/rtl.md.

Every layout is an ``amaranth.lib.data.StructLayout``: first field at bit 0 of the packed
vector the Verilog port carries.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth import signed, unsigned
from amaranth.lib import data

from models.datapath import Datapath
from rtl.classify import entry_bits as classify_entry_bits
from rtl.common import bit_length
from rtl.composite import TABLE_ENTRIES
from rtl.shade import MAP_BITS, map_entries

__all__ = [
    "TopGeometry",
    "LOAD_LUT",
    "LOAD_CORRECTION",
    "LOAD_RAYS",
    "LOAD_SLICES",
    "LOAD_GM",
    "LOAD_SPEC",
    "LOAD_DIFFUSE_MAP",
    "slice_layout",
    "ray_layout",
    "pixel_layout",
    "buffer_layout",
    "load_layout",
    "load_words_bound",
]

# Load targets (0 was the volume, which now lives outside the chip: ``vmem_*`` ports).
# LOAD_SPEC is the Phong shader's specular table or the reflectance-map shader's specular
# map; LOAD_DIFFUSE_MAP the latter's diffuse map (rtl/shade.py).
LOAD_LUT, LOAD_CORRECTION, LOAD_RAYS, LOAD_SLICES, LOAD_GM, LOAD_SPEC = range(1, 7)
LOAD_DIFFUSE_MAP = 7


@dataclass(frozen=True)
class TopGeometry:
    """Elaboration sizes: pipelines ``P``, voxels per axis at most ``N``."""

    pipelines: int
    max_axis: int = 16

    @property
    def c_max(self) -> int:
        return -(-self.max_axis // self.pipelines)

    @property
    def t_max(self) -> int:
        """Slots of the largest slice per pipeline."""
        return self.max_axis * self.c_max

    @property
    def module_words(self) -> int:
        """Words of one voxel memory module (outside the chip)."""
        return self.max_axis * self.max_axis * self.c_max

    @property
    def module_addr_bits(self) -> int:
        return bit_length(self.module_words - 1)

    @property
    def max_rays(self) -> int:
        """Base-plane rays: shear <= 1 per slice, so at most ``2N`` per axis."""
        return 4 * self.max_axis * self.max_axis

    @property
    def axis_bits(self) -> int:
        return bit_length(self.max_axis)

    @property
    def ray_bits(self) -> int:
        return bit_length(self.max_rays - 1)

    @property
    def offset_bits(self) -> int:
        """Signed base-plane offsets ``ia``, ``ib`` in ``[-2N, 2N]``."""
        return bit_length(2 * self.max_axis) + 1


def slice_layout(geo: TopGeometry, dp: Datapath):
    """One step's constants: slice ``q`` (and ``q mod P``), cell shift ``da``/``db``,
    base-plane offsets ``ia``/``ib`` (cell = ray coordinate + offset) and weights
    ``wa``/``wb``: what the host's geometry unit gives for a parallel view; the crop
    box's slabs on this slice (``crop_k``: the slice inside the principal axis's slab;
    ``crop_a_lo .. crop_a_hi``, ``crop_b_lo .. crop_b_hi``: the cells whose samples are
    inside the in-slice axes' slabs); nothing about timing."""
    ab = geo.axis_bits
    w = dp.interp.weight.width
    cell = signed(ab + 2)
    return data.StructLayout(
        {
            "q": unsigned(ab),
            "qm": unsigned(bit_length(geo.pipelines)),
            "da": unsigned(1),
            "db": unsigned(1),
            "ia": signed(geo.offset_bits),
            "ib": signed(geo.offset_bits),
            "wa": unsigned(w),
            "wb": unsigned(w),
            "crop_k": unsigned(1),
            "crop_a_lo": cell,
            "crop_a_hi": cell,
            "crop_b_lo": cell,
            "crop_b_hi": cell,
        }
    )


def ray_layout(geo: TopGeometry):
    """A base-plane ray's first and last step (``j_lo <= j <= j_hi``)."""
    return data.StructLayout({"j_lo": unsigned(geo.axis_bits), "j_hi": unsigned(geo.axis_bits)})


def pixel_layout(geo: TopGeometry, dp: Datapath):
    """What the pixel bus delivers: the ray and its accumulators (UQ1.F RGBA, raw MIP)."""
    sample_bits = dp.voxel_bits + dp.interp.sample_frac_bits
    return data.StructLayout(
        {
            "ray": unsigned(geo.ray_bits),
            "acc": data.ArrayLayout(unsigned(dp.composite.acc_frac_bits + 1), 4),
            "mip": unsigned(sample_bits),
        }
    )


def buffer_layout(dp: Datapath):
    """A compositing-buffer entry: ``acc[4]`` (UQ1.F), ``mip`` (raw) and ``alive``."""
    sample_bits = dp.voxel_bits + dp.interp.sample_frac_bits
    return data.StructLayout(
        {
            "acc": data.ArrayLayout(unsigned(dp.composite.acc_frac_bits + 1), 4),
            "mip": unsigned(sample_bits),
            "alive": unsigned(1),
        }
    )


def load_layout(geo: TopGeometry, dp: Datapath):
    """``target`` (LOAD_*), ``addr`` and ``data``: LUT entries, correction-table entries,
    ray and slice records as their layouts pack them; gradient-magnitude table entries and
    the shader's tables: Phong's specular table (UQ1.12) or the two reflectance maps
    (UQ8.12, ``6 R^2 + 1`` entries each)."""
    widths = [
        classify_entry_bits(dp.classify),
        13,
        ray_layout(geo).size,
        slice_layout(geo, dp).size,
        13,
        MAP_BITS if _maps(dp) else 13,
    ]
    depth = max(
        dp.classify.entries,
        TABLE_ENTRIES,
        geo.max_rays,
        geo.max_axis,
        dp.classify.gm_entries,
        map_entries(dp.shade) if _maps(dp) else dp.shade.spec_table_entries + 1,
    )
    return data.StructLayout(
        {
            "target": unsigned(3),
            "addr": unsigned(bit_length(depth - 1)),
            "data": unsigned(max(widths)),
        }
    )


def _maps(dp: Datapath) -> bool:
    """Whether the shader looks its light up in reflectance maps (else per-sample Phong)."""
    return dp.shade.method == "reflectance-map"


def load_words_bound(geo: TopGeometry, dp: Datapath) -> int:
    """The most load words one frame writes: the ray table, the slice table and every
    table once (the shader's: Phong's specular table or both reflectance maps)."""
    shader = 2 * map_entries(dp.shade) if _maps(dp) else dp.shade.spec_table_entries + 1
    return (
        geo.max_rays
        + geo.max_axis
        + 2
        + dp.classify.entries
        + TABLE_ENTRIES
        + dp.classify.gm_entries
        + shader
    )
