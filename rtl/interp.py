"""Trilinear interpolator RTL: seven lerps, x then y then z, bit-exact with
``models.units.interp.interpolate``.

# Ref: architectures.md sections 1.3, 6.4 and 9.1 (TriLin); models/units/interp.py.

Stages (``LATENCY = 4``, ``II = 1``): input register (voxels promoted by ``S`` fraction
bits), four x lerps, two y lerps, one z lerp.  ``lerp(a, b, f) = a + round((b - a) f /
2**W)`` with the config's rounding, as the model.
"""

from __future__ import annotations

from amaranth import Module, signed, unsigned
from amaranth.lib import data, wiring

from models.units.interp import InterpConfig
from rtl.common import StallingPipeline, round_shift, unit_ports

__all__ = [
    "Interp",
    "LATENCY",
    "II",
    "STAGES",
    "input_layout",
    "lerp",
    "lerp_stages",
    "output_layout",
    "sample_shape",
]

#: The stage plan: one name per register stage (``LATENCY`` is its length, the RTL's own;
#: ``models.units.interp.LATENCY`` must equal it, as the unit tests check).  Each lerp is
#: two stages: the product ``(b - a) f``, then ``a +`` its rounded shift.
STAGES = ("promote", "x_product", "x_sum", "y_product", "y_sum", "z_product", "z_sum")
LATENCY = len(STAGES)
II = 1


def sample_shape(cfg: InterpConfig, voxel_bits: int):
    """Signed width of voxels promoted by ``S`` and of every lerp between them."""
    return signed(voxel_bits + cfg.sample_frac_bits + 1)


def lerp(a, b, f, cfg: InterpConfig):
    """``a + (b - a) f`` for a ``W``-bit weight ``f``, rounded as the model's lerp."""
    return lerp_sum(a, lerp_product(a, b, f), cfg)


def lerp_product(a, b, f):
    """The first stage of a pipelined :func:`lerp`: ``(b - a) f``."""
    return (b - a) * f


def lerp_sum(a, product, cfg: InterpConfig):
    """The second stage of a pipelined :func:`lerp`: ``a + round(product / 2**W)``."""
    return a + round_shift(product, cfg.weight_bits, cfg.rounding)


def lerp_stages(pipe, pairs, f, cfg: InterpConfig, wide, name: str) -> list:
    """The lerps of ``pairs`` ``(a, b)`` at weight ``f`` over two stages of ``pipe``
    (product, then sum): the registered results, ``wide`` each."""
    products = [
        pipe.register(lerp_product(a, b, f), name=f"{name}{k}_p") for k, (a, b) in enumerate(pairs)
    ]
    ends = [pipe.register(a, name=f"{name}{k}_a") for k, (a, _) in enumerate(pairs)]
    return [
        pipe.register(lerp_sum(ends[k], products[k], cfg), name=f"{name}{k}", shape=wide)
        for k in range(len(pairs))
    ]


def input_layout(cfg: InterpConfig, voxel_bits: int, signed_input: bool = False):
    """``voxels[8]`` (corner ``c = 4 dz + 2 dy + dx``) and ``frac[3]`` (raw UQ1.W along
    ``(z, y, x)``), as :class:`models.units.interp.InterpTaps` orders them."""
    shape = signed(voxel_bits) if signed_input else unsigned(voxel_bits)
    return data.StructLayout(
        {
            "voxels": data.ArrayLayout(shape, 8),
            "frac": data.ArrayLayout(unsigned(cfg.weight.width), 3),
        }
    )


def output_layout(cfg: InterpConfig, voxel_bits: int, signed_input: bool = False):
    """``sample``: the voxel format plus ``S`` fraction bits (a lerp stays between its
    ends, so no integer bit is added)."""
    width = voxel_bits + cfg.sample_frac_bits
    return data.StructLayout({"sample": signed(width) if signed_input else unsigned(width)})


class Interp(wiring.Component):
    """Trilinear interpolator.

    Parameters
    ----------
    cfg : InterpConfig
        Weight bits ``W``, sample fraction bits ``S``, rounding.
    voxel_bits : int
        Width of the voxels entering (``B``; ``B + 2`` signed for voxel differences).
    signed_input : bool
        Two's-complement voxels (gradient differences at voxels).
    """

    def __init__(
        self, cfg: InterpConfig | None = None, voxel_bits: int = 12, signed_input: bool = False
    ):
        cfg = cfg if cfg is not None else InterpConfig()
        self.cfg, self.voxel_bits, self.signed_input = cfg, voxel_bits, signed_input
        layouts = (
            layout(cfg, voxel_bits, signed_input) for layout in (input_layout, output_layout)
        )
        super().__init__(unit_ports(*layouts))

    def elaborate(self, platform):
        m = Module()
        cfg, s = self.cfg, self.cfg.sample_frac_bits
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        wide, payload = sample_shape(cfg, self.voxel_bits), self.i.payload
        v = [pipe.register(payload.voxels[c] << s, name=f"v{c}", shape=wide) for c in range(8)]
        fz, fy, fx = (pipe.register(payload.frac[k], name=f"f{k}") for k in range(3))
        # The fractions travel with their samples, one register per stage.
        x = lerp_stages(pipe, [(v[c], v[c + 1]) for c in (0, 2, 4, 6)], fx, cfg, wide, "x")
        fy, fz = pipe.delay(fy, 2, name="fy"), pipe.delay(fz, 2, name="fz")
        y = lerp_stages(pipe, [(x[0], x[1]), (x[2], x[3])], fy, cfg, wide, "y")
        fz = pipe.delay(fz, 2, name="fz_y")
        (z,) = lerp_stages(pipe, [(y[0], y[1])], fz, cfg, wide, "z")
        m.d.comb += self.o.payload.sample.eq(z)
        return m
