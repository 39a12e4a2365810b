"""Skewed-memory address generator RTL: Cube-4 module/address and VolumePro 500 two-level
mini-block module/bank/address of a voxel, bit-exact with ``models.units.skew``.

# Ref: architectures.md sections 1.2 (Cube-4 skew) and 3 (VolumePro 500 two-level
#      mini-blocks, [I] formulas); models/units/skew.py.

Three register stages (``STAGES``; ``LATENCY = 3``, ``II = 1``), so every stage meets a
125 MHz clock at 0.35 um by the project's depth estimate (issue 34: one stage was 52
generic gates deep, ~102 MHz): ``row`` (the row pitches, ``z n + y`` and the coordinate
sums), ``linear`` (the second product, the linear word index; the modules) and
``address`` (the divisions by the module and bank counts).  The volume size ``n`` is a
static configuration input (a register the host writes before a pass); the module and
bank counts are elaboration constants, so every ``div`` / ``mod`` by them is a shift or a
reciprocal multiply, and the row pitches are computed from ``n`` the same way.
"""

from __future__ import annotations

from amaranth import Module, Signal, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In

from models.units.skew import SkewConfig
from rtl.common import StallingPipeline, bit_length, divide_by_constant, unit_ports

__all__ = ["Skew", "LATENCY", "II", "input_layout", "output_layout", "address_bits"]

#: The stage plan: one name per register stage (``LATENCY`` is its length, the RTL's own;
#: ``models.units.skew.LATENCY`` must equal it, as the unit tests check).
STAGES = ("row", "linear", "address")
LATENCY = len(STAGES)
II = 1


def _pitch(n: int, p: int) -> int:
    return -(-n // p) * p


def address_bits(cfg: SkewConfig) -> tuple[int, int]:
    """Widths of the Cube-4 and VolumePro 500 word addresses at ``n = max_size``."""
    n, p, mk = cfg.max_size, cfg.modules, cfg.modules * cfg.banks
    cube4 = ((n - 1) * n + n - 1) * _pitch(n, p) + n - 1
    nb = -(-n // 2)
    lb = ((nb - 1) * nb + nb - 1) * _pitch(nb, mk) + nb - 1
    return bit_length(cube4 // p), bit_length(((lb // mk) << 3) | 7)


def input_layout(cfg: SkewConfig):
    """Voxel coordinates ``x, y, z`` (``0 .. max_size - 1``)."""
    c = unsigned(bit_length(cfg.max_size - 1))
    return data.StructLayout({"x": c, "y": c, "z": c})


def output_layout(cfg: SkewConfig):
    """Cube-4 ``module, address``; VolumePro 500 ``vp_module, vp_bank, vp_address``."""
    a4, a5 = address_bits(cfg)
    return data.StructLayout(
        {
            "module": unsigned(bit_length(cfg.modules - 1)),
            "address": unsigned(a4),
            "vp_module": unsigned(bit_length(cfg.modules - 1)),
            "vp_bank": unsigned(bit_length(cfg.banks - 1)),
            "vp_address": unsigned(a5),
        }
    )


class Skew(wiring.Component):
    """Address generator of the skewed volume memory.

    Parameters
    ----------
    cfg : SkewConfig
        ``modules`` (Cube-4 ``P`` and VolumePro 500 ``M``), ``banks`` (``K``),
        ``max_size`` (largest ``n``, sets the widths).

    Ports
    -----
    i, o : stream
        :func:`input_layout` in, :func:`output_layout` out.
    n : In
        Voxels per axis of the volume (static during a pass, ``1 .. max_size``).
    """

    def __init__(self, cfg: SkewConfig | None = None):
        cfg = cfg if cfg is not None else SkewConfig()
        self.cfg = cfg
        ports = unit_ports(input_layout(cfg), output_layout(cfg), n=In(bit_length(cfg.max_size)))
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        cfg = self.cfg
        p, k = cfg.modules, cfg.banks
        mk = p * k
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        x, y, z = self.i.payload.x, self.i.payload.y, self.i.payload.z
        nbits = bit_length(cfg.max_size)

        def div(value, d):
            value_bits = value.shape().width
            return divide_by_constant(value, d, value_bits)

        def mod(value, d):
            return value - div(value, d) * d

        reg = pipe.register
        # Stage "row": the pitches, the first product of each layout, the coordinate sums.
        # Cube-4: module (x + y + z) mod P, address ((z n + y) nx + x) div P.
        a4_bits, a5_bits = address_bits(cfg)
        xyz_bits = bit_length(3 * (cfg.max_size - 1))
        nx = reg(div(self.n + (p - 1), p) * p, name="nx", shape=nbits + bit_length(p))
        row = reg(z * self.n + y, name="row", shape=2 * nbits)
        total = reg(x + y + z, name="xyz", shape=xyz_bits)
        x1 = reg(x, name="x1")
        # VolumePro 500: mini-block b = (x, y, z) >> 1, s = bx + by + bz.
        bx, by, bz = x >> 1, y >> 1, z >> 1
        nb = Signal(nbits, name="nb")
        m.d.comb += nb.eq((self.n + 1) >> 1)
        nbx = reg(div(nb + (mk - 1), mk) * mk, name="nbx", shape=nbits + bit_length(mk))
        brow = reg(bz * nb + by, name="brow", shape=2 * nbits)
        s = reg(bx + by + bz, name="s", shape=xyz_bits)
        bx1 = reg(bx, name="bx1")
        offset = reg((z[0] << 2) | (y[0] << 1) | x[0], name="offset", shape=3)

        # Stage "linear": the word index of each layout; the modules; s div M.
        linear = reg(row * nx + x1, name="linear", shape=a4_bits + bit_length(p))
        lb = reg(brow * nbx + bx1, name="lb", shape=a5_bits + bit_length(mk))
        module = reg(mod(total, p), name="module2")
        vp_module = reg(mod(s, p), name="vp_module2")
        s_div_m = reg(div(s, p), name="s_div_m", shape=xyz_bits)
        offset2 = reg(offset, name="offset2")

        # Stage "address": the divisions by the module and bank counts.
        out = self.o.payload
        fields = {
            "module": module,
            "address": div(linear, p),
            "vp_module": vp_module,
            "vp_bank": mod(s_div_m, k),
            "vp_address": (div(lb, mk) << 3) | offset2,
        }
        for name, value in fields.items():
            m.d.comb += getattr(out, name).eq(
                pipe.register(value, name=name, shape=getattr(out, name).shape())
            )
        return m
