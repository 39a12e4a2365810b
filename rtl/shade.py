"""Shader RTL: reflectance-map lookups by normal direction plus the Phong combine,
bit-exact with ``models.units.shade.shade`` for ``method = "reflectance-map"``.

# Ref: architectures.md section 3 (VolumePro 500 reflectance maps: diffuse and specular
#      maps looked up by gradient direction, any number of lights); models/units/shade.py.

Stages (``LATENCY = 4``, ``II = 1``):

1. cube-map face: the largest ``|N|`` component (first of x, y, z on ties), its sign,
   and the two other components ``u, w``;
2. cell: ``i = clamp(floor((u + |N|max) R / (2 |N|max)), 0, R - 1)`` for ``u`` and ``w``
   (two exact ``bits(R)``-step dividers); entry ``((2 axis + sign) R + iu) R + iw``, or
   ``6 R^2`` for the zero normal;
3. diffuse and specular map reads (synchronous SRAMs, loaded through ``load``);
4. ``clamp(round(ka c / 2**8) + round(diffuse c / 2**12) + specular, 0, 4096)``.

The maps are computed on the host (:func:`models.units.shade.setup`: one entry per cube
cell, summed over all lights) and written through the always-ready ``load`` port
(``table = 0`` diffuse, ``1`` specular); an entry is ``MAP_BITS`` wide (UQ8.12, room
for the light sum of ``I kd`` up to 256).
"""

from __future__ import annotations

from amaranth import Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from models.units import shade as model
from models.units.shade import ShadeConfig
from rtl.common import StallingPipeline, bit_length, divide_bounded, round_shift

__all__ = ["Shade", "LATENCY", "II", "input_layout", "output_layout", "load_layout", "MAP_BITS"]

LATENCY = model.LATENCY
II = model.II
ONE = 1 << 12
ONE_BITS = 13
COEF_BITS = 12  # UQ4.8 (models.units.shade._COEF = 8 fraction bits)
MAP_BITS = 20  # UQ8.12


def input_layout(cfg: ShadeConfig):
    """``rgb[3]`` UQ1.12 and ``normal[3]`` SQ1.F ``(x, y, z)``."""
    return data.StructLayout(
        {
            "rgb": data.ArrayLayout(unsigned(ONE_BITS), 3),
            "normal": data.ArrayLayout(signed(cfg.normal_frac_bits + 2), 3),
        }
    )


def output_layout():
    """Shaded ``rgb[3]`` in UQ1.12 (saturated at 1.0)."""
    return data.StructLayout({"rgb": data.ArrayLayout(unsigned(ONE_BITS), 3)})


def map_entries(cfg: ShadeConfig) -> int:
    """``6 R^2`` cube cells plus the zero-normal entry."""
    return 6 * cfg.map_size * cfg.map_size + 1


def load_layout(cfg: ShadeConfig):
    """``table`` (0 diffuse, 1 specular), ``addr``, ``data`` (UQ8.12)."""
    return data.StructLayout(
        {
            "table": unsigned(1),
            "addr": unsigned(bit_length(map_entries(cfg) - 1)),
            "data": unsigned(MAP_BITS),
        }
    )


class Shade(wiring.Component):
    """Reflectance-map shader.

    Parameters
    ----------
    cfg : ShadeConfig
        ``normal_frac_bits`` (F) and ``map_size`` (R); ``method`` must be
        ``"reflectance-map"``.

    Ports
    -----
    i, o : stream
        :func:`input_layout` in, :func:`output_layout` out.
    load : In stream, always ready
        :func:`load_layout` map writes.
    ka : In(12)
        Ambient coefficient, UQ4.8.
    """

    def __init__(self, cfg: ShadeConfig | None = None):
        cfg = cfg if cfg is not None else ShadeConfig(method="reflectance-map")
        if cfg.method != "reflectance-map":
            self._MustUse__silence = True  # never elaborated: no "created but never used"
            raise ValueError("rtl.shade implements method = 'reflectance-map'")
        self.cfg = cfg
        super().__init__(
            {
                "i": In(stream.Signature(input_layout(cfg))),
                "o": Out(stream.Signature(output_layout())),
                "load": In(stream.Signature(load_layout(cfg), always_ready=True)),
                "ka": In(COEF_BITS),
            }
        )

    def elaborate(self, platform):
        m = Module()
        f, r = self.cfg.normal_frac_bits, self.cfg.map_size
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        nbits = f + 2
        n = self.i.payload.normal

        # Stage 1: major axis, sign, the two other components.
        mag = []
        for k in range(3):
            a = Signal(unsigned(nbits), name=f"abs{k}")
            m.d.comb += a.eq(Mux(n[k] < 0, -n[k], n[k]))
            mag.append(a)
        axis = Signal(range(3), name="axis")
        with m.If((mag[0] >= mag[1]) & (mag[0] >= mag[2])):
            m.d.comb += axis.eq(0)
        with m.Elif(mag[1] >= mag[2]):
            m.d.comb += axis.eq(1)
        with m.Else():
            m.d.comb += axis.eq(2)
        major = Mux(axis == 0, mag[0], Mux(axis == 1, mag[1], mag[2]))
        sign = Mux(axis == 0, n[0] < 0, Mux(axis == 1, n[1] < 0, n[2] < 0))
        u = Mux(axis == 0, n[1], n[0])
        w = Mux(axis == 2, n[1], n[2])
        major1 = pipe.register(major, name="major", shape=unsigned(nbits))
        axis1 = pipe.register(axis, name="axis1")
        sign1 = pipe.register(sign, name="sign1")
        u1 = pipe.register(u, name="u1", shape=signed(nbits))
        w1 = pipe.register(w, name="w1", shape=signed(nbits))
        rgb1 = [pipe.register(self.i.payload.rgb[k], name=f"rgb1_{k}") for k in range(3)]

        # Stage 2: cube-map cell.
        safe = Signal(unsigned(nbits), name="safe")
        m.d.comb += safe.eq(Mux(major1 == 0, 1, major1))
        qbits = bit_length(r)
        cells = []
        for name, comp in (("iu", u1), ("iw", w1)):
            num = Signal(unsigned(nbits + 1 + qbits), name=f"{name}_num")
            m.d.comb += num.eq((comp + safe).as_unsigned() * r)
            q = divide_bounded(m, num, safe << 1, qbits, name=f"{name}_div")
            cells.append(Mux(q > r - 1, r - 1, q))
        index = Mux(major1 == 0, 6 * r * r, (((axis1 << 1) | sign1) * r + cells[0]) * r + cells[1])
        index2 = pipe.register(
            index, name="cell", shape=unsigned(bit_length(map_entries(self.cfg) - 1))
        )
        rgb2 = [pipe.register(rgb1[k], name=f"rgb2_{k}") for k in range(3)]

        # Stage 3: map reads.
        reads = []
        for table, label in ((0, "diffuse"), (1, "specular")):
            mem = Memory(shape=unsigned(MAP_BITS), depth=map_entries(self.cfg), init=[])
            m.submodules[label] = mem
            wr = mem.write_port()
            m.d.comb += [
                wr.addr.eq(self.load.payload.addr),
                wr.data.eq(self.load.payload.data),
                wr.en.eq(self.load.valid & (self.load.payload.table == table)),
            ]
            rd = mem.read_port()
            m.d.comb += [rd.addr.eq(index2), rd.en.eq(pipe.advance)]
            reads.append(rd.data)
        rgb3 = [pipe.register(rgb2[k], name=f"rgb3_{k}") for k in range(3)]

        # Stage 4: Phong combine.
        diffuse, specular = reads
        for k in range(3):
            lit = (
                round_shift(self.ka * rgb3[k], 8, "nearest-up")
                + round_shift(diffuse * rgb3[k], 12, "nearest-up")
                + specular
            )
            out = Mux(lit > ONE, ONE, lit)
            m.d.comb += self.o.payload.rgb[k].eq(
                pipe.register(out, name=f"lit{k}", shape=unsigned(ONE_BITS))
            )
        return m
