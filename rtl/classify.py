"""Classifier RTL: RGBA lookup table with a load port, unorm -> UQ1.12 read-out, and
gradient-magnitude opacity modulation; bit-exact with ``models.units.classify``
(``lut_index``, ``classify``, ``expand``, ``gm_index``, ``modulate``).

# Ref: architectures.md sections 3 and 4 (VolumePro 500 / 1000 classification LUT,
#      gradient-magnitude modulation table); models/units/classify.py.

Stages (``LATENCY = 2``, ``II = 1``): the nearest entry ``round(sample / 2**shift)``
(clamped) and the gradient-magnitude index ``round(|g| scale / 2**24)`` (clamped) address
two synchronous SRAMs; then the stored unorm RGB and alpha expand to UQ1.12 by a
constant reciprocal multiply (``round(x 4096 / (2**n - 1))``) and alpha is modulated
``round(alpha gm[i] / 4096)`` when ``modulate`` is set.

The ``load`` port (always ready) writes one entry per cycle: ``table = 0`` the RGBA LUT
(``data = r | g << c | b << 2c | a << 3c``, unorm as stored), ``table = 1`` the
magnitude table (UQ1.12).  Loads and lookups may share a cycle; a lookup of the entry
being written reads the old value.
"""

from __future__ import annotations

from amaranth import Module, Mux, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In

from models.units.classify import ClassifyConfig
from rtl.common import (
    StallingPipeline,
    bit_length,
    divide_by_constant,
    load_port,
    round_shift,
    unit_ports,
)

__all__ = ["Classify", "LATENCY", "II", "input_layout", "output_layout", "load_layout"]

#: The stage plan: one name per register stage (``LATENCY`` is its length, the RTL's own;
#: ``models.units.classify.LATENCY`` must equal it, as the unit tests check).
STAGES = ("index", "read", "expand", "modulate")
LATENCY = len(STAGES)
II = 1
ONE_BITS = 13  # UQ1.12: 4096 = 1.0
GM_SCALE_BITS = 24  # models.units.classify._GM_SCALE_BITS


def input_layout(sample_bits: int):
    """``sample`` (``B + S`` bits) and ``magnitude`` (``floor(|g|)``, ``B + S + 3`` bits,
    the gradient unit's output)."""
    return data.StructLayout(
        {"sample": unsigned(sample_bits), "magnitude": unsigned(sample_bits + 3)}
    )


def output_layout():
    """``rgb[3]`` and ``alpha`` in UQ1.12."""
    return data.StructLayout(
        {"rgb": data.ArrayLayout(unsigned(ONE_BITS), 3), "alpha": unsigned(ONE_BITS)}
    )


def entry_bits(cfg: ClassifyConfig) -> int:
    """Stored bits of one RGBA entry."""
    return 3 * cfg.color_bits + cfg.alpha_bits


def load_layout(cfg: ClassifyConfig):
    """``table`` (0 RGBA, 1 magnitude), ``addr``, ``data``."""
    return data.StructLayout(
        {
            "table": unsigned(1),
            "addr": unsigned(bit_length(max(cfg.entries, cfg.gm_entries) - 1)),
            "data": unsigned(max(entry_bits(cfg), ONE_BITS)),
        }
    )


def _expand(value, bits: int):
    """``(x 8192 + full) // (2 full)``: :func:`models.units.classify.expand`."""
    full = (1 << bits) - 1
    numerator = value * (2 << 12) + full
    return divide_by_constant(numerator, 2 * full, bits + 14)


class Classify(wiring.Component):
    """Post-classification LUT with gradient-magnitude modulation.

    Parameters
    ----------
    cfg : ClassifyConfig
    voxel_bits, sample_frac_bits : int
        ``B`` and ``S`` of the samples that index the table.

    Ports
    -----
    i, o : stream
        :func:`input_layout` in, :func:`output_layout` out.
    load : In stream, always ready
        :func:`load_layout` table writes.
    gm_scale : In(32)
        UQ0.24 magnitude-to-index constant (:func:`models.units.classify.gm_scale`).
    modulate : In(1)
        Multiply alpha by the magnitude table.
    """

    def __init__(
        self,
        cfg: ClassifyConfig | None = None,
        voxel_bits: int = 12,
        sample_frac_bits: int = 4,
    ):
        cfg = cfg if cfg is not None else ClassifyConfig()
        self.cfg, self.voxel_bits, self.sample_frac_bits = cfg, voxel_bits, sample_frac_bits
        self.sample_bits = voxel_bits + sample_frac_bits
        ports = unit_ports(
            input_layout(self.sample_bits),
            output_layout(),
            load=load_port(load_layout(cfg)),
            gm_scale=In(32),
            modulate=In(1),
        )
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        cfg = self.cfg
        c, a = cfg.color_bits, cfg.alpha_bits
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        m.submodules.lut = lut = Memory(shape=unsigned(entry_bits(cfg)), depth=cfg.entries, init=[])
        m.submodules.gm = gm = Memory(shape=unsigned(ONE_BITS), depth=cfg.gm_entries, init=[])
        for mem, table in ((lut, 0), (gm, 1)):
            wr = mem.write_port()
            m.d.comb += [
                wr.addr.eq(self.load.payload.addr),
                wr.data.eq(self.load.payload.data),
                wr.en.eq(self.load.valid & (self.load.payload.table == table)),
            ]

        # "index": the two tables' entries.
        shift = self.sample_bits - (cfg.entries.bit_length() - 1)
        index = round_shift(self.i.payload.sample, shift, "nearest-up")
        lut_index = pipe.register(
            Mux(index > cfg.entries - 1, cfg.entries - 1, index), name="lut_index"
        )
        product = pipe.register(self.i.payload.magnitude * self.gm_scale, name="gm_product")

        # "read": the two synchronous SRAMs.
        scaled = round_shift(product, GM_SCALE_BITS, "nearest-up")
        gm_index = Mux(scaled > cfg.gm_entries - 1, cfg.gm_entries - 1, scaled)
        lut_rd = lut.read_port()
        gm_rd = gm.read_port()
        m.d.comb += [
            lut_rd.addr.eq(lut_index),
            lut_rd.en.eq(pipe.advance),
            gm_rd.addr.eq(gm_index),
            gm_rd.en.eq(pipe.advance),
        ]

        # "expand": unorm -> UQ1.12.
        entry = lut_rd.data
        rgb = [
            pipe.register(_expand(entry[k * c : (k + 1) * c], c), name=f"rgb{k}", shape=ONE_BITS)
            for k in range(3)
        ]
        alpha = pipe.register(_expand(entry[3 * c : 3 * c + a], a), name="alpha12", shape=ONE_BITS)
        gm_value = pipe.register(gm_rd.data, name="gm_value")

        # "modulate": alpha times the magnitude table's entry.
        out = self.o.payload
        for k in range(3):
            m.d.comb += out.rgb[k].eq(pipe.register(rgb[k], name=f"rgb_out{k}"))
        modulated = round_shift(alpha * gm_value, 12, "nearest-up")
        m.d.comb += out.alpha.eq(
            pipe.register(
                Mux(self.modulate, modulated, alpha), name="alpha", shape=unsigned(ONE_BITS)
            )
        )
        return m
