"""Shader RTL: reflectance-map lookups by normal direction (VolumePro 500) or per-sample
Phong dot products (VIZARD II), plus the Phong combine; bit-exact with
``models.units.shade.shade`` for both methods.

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

``method = "phong"`` replaces stages 1-3 by: ``N.L`` and ``N.H`` per light (static light
and half vectors: parallel projection), rounded to UQ1.12 and clamped; the specular
table ``x**n`` (SRAM, one read port per light) indexed by ``round(N.H entries)``; the
diffuse ``round(I kd min(N.L, 1) / 2**16)`` and specular ``round(I ks spec / 2**16)``
terms summed over the lights.

The maps are computed on the host (:func:`models.units.shade.setup`: one entry per cube
cell, summed over all lights) and written through the always-ready ``load`` port
(``table = 0`` diffuse, ``1`` specular); an entry is ``MAP_BITS`` wide (UQ8.12, room
for the light sum of ``I kd`` up to 256).
"""

from __future__ import annotations

from amaranth import Cat, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In

from models.units.shade import ShadeConfig
from rtl.common import (
    StallingPipeline,
    bit_length,
    divide_bounded,
    load_port,
    round_shift,
    unit_ports,
)

__all__ = [
    "Shade",
    "LATENCY",
    "II",
    "input_layout",
    "output_layout",
    "load_layout",
    "map_entries",
    "MAP_BITS",
]

#: The reflectance-map cell dividers' steps are spread over these many stages.
DIVIDE_STAGES = 4
#: The stage plan: one name per register stage (``LATENCY`` is its length, the RTL's own;
#: ``models.units.shade.LATENCY`` must equal it, as the unit tests check).  The Phong
#: method fills the same ``FRONT`` stages before the combine (its own plan in
#: :meth:`Shade._phong`, padded).
FRONT = ("face", "numerator", *("divide",) * DIVIDE_STAGES, "cell", "read")
STAGES = (*FRONT, "products", "sum")
LATENCY = len(STAGES)
II = 1
#: The Phong front end's own stages: products, dot products, clamp and table index, table
#: read and coefficient products, per-light terms, light sums.
PHONG_FRONT = 6
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
    """``table`` (0 diffuse, 1 specular map), ``addr``, ``data`` (UQ8.12); with
    ``method = "phong"`` the specular ``x**n`` table (``addr`` 0 .. entries, UQ1.12)."""
    entries = map_entries(cfg) if cfg.method == "reflectance-map" else cfg.spec_table_entries + 1
    return data.StructLayout(
        {
            "table": unsigned(1),
            "addr": unsigned(bit_length(entries - 1)),
            "data": unsigned(MAP_BITS),
        }
    )


class Shade(wiring.Component):
    """Reflectance-map or per-sample Phong shader.

    Parameters
    ----------
    cfg : ShadeConfig
        ``method``, ``normal_frac_bits`` (F), ``map_size`` (R), ``spec_table_entries``.
    lights : int
        Directional lights of the Phong method (the maps already sum any number).

    Ports
    -----
    i, o : stream
        :func:`input_layout` in, :func:`output_layout` out.
    load : In stream, always ready
        :func:`load_layout` map (or specular table) writes.
    ka : In(12)
        Ambient coefficient, UQ4.8.
    light, half : In, Phong only
        ``lights`` vectors of three SQ1.F components ``(x, y, z)``.
    intensity : In, Phong only
        ``lights`` UQ4.8 intensities.
    kd, ks : In(12), Phong only
        Diffuse and specular coefficients, UQ4.8.
    """

    def __init__(self, cfg: ShadeConfig | None = None, lights: int = 1):
        cfg = cfg if cfg is not None else ShadeConfig(method="reflectance-map")
        if lights < 1:
            self._MustUse__silence = True  # never elaborated: no "created but never used"
            raise ValueError("rtl.shade: lights >= 1")
        self.cfg, self.lights = cfg, lights
        members = unit_ports(
            input_layout(cfg), output_layout(), load=load_port(load_layout(cfg)), ka=In(COEF_BITS)
        )
        if cfg.method == "phong":
            vector = data.ArrayLayout(signed(cfg.normal_frac_bits + 2), 3)
            members.update(
                {
                    "light": In(data.ArrayLayout(vector, lights)),
                    "half": In(data.ArrayLayout(vector, lights)),
                    "intensity": In(data.ArrayLayout(unsigned(COEF_BITS), lights)),
                    "kd": In(COEF_BITS),
                    "ks": In(COEF_BITS),
                }
            )
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        if self.cfg.method == "phong":
            diffuse, specular = self._phong(m, pipe)
        else:
            diffuse, specular = self._reflectance_maps(m, pipe)
        rgb = [
            pipe.delay(self.i.payload.rgb[k], len(FRONT), name=f"rgb_front{k}") for k in range(3)
        ]
        self._combine(m, pipe, rgb, diffuse, specular)
        return m

    def _reflectance_maps(self, m, pipe):
        """The ``FRONT`` stages of the reflectance-map method: face, cell, map reads."""
        f, r = self.cfg.normal_frac_bits, self.cfg.map_size
        nbits = f + 2
        n = self.i.payload.normal

        # "face": major axis, sign, the two other components.
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

        # "numerator": (c + |N|max) R and the divisor 2 |N|max (1 for the zero normal).
        safe = Signal(unsigned(nbits), name="safe")
        m.d.comb += safe.eq(Mux(major1 == 0, 1, major1))
        qbits = bit_length(r)
        nums = [
            pipe.register(
                (comp + safe).as_unsigned() * r, name=f"{name}_num", shape=nbits + 1 + qbits
            )
            for name, comp in (("iu", u1), ("iw", w1))
        ]
        divisor = pipe.register(safe << 1, name="divisor")
        face = pipe.register(Cat(sign1, axis1, major1 == 0), name="face")

        # "divide" x DIVIDE_STAGES: the cell along u and w.
        cells = []
        for name, num in zip(("iu", "iw"), nums, strict=True):
            q = divide_bounded(
                m, num, divisor, qbits, name=f"{name}_div", pipe=pipe, stages=DIVIDE_STAGES
            )
            q = pipe.register(q, name=f"{name}_q")
            cells.append(Mux(q > r - 1, r - 1, q))
        face = pipe.delay(face, DIVIDE_STAGES, name="face_div")

        # "cell": the map entry, ``6 R^2`` for the zero normal.
        side, zero = face[:3], face[3]
        index = Mux(zero, 6 * r * r, (side * r + cells[0]) * r + cells[1])
        index2 = pipe.register(
            index, name="cell", shape=unsigned(bit_length(map_entries(self.cfg) - 1))
        )

        # "read": the two maps (synchronous SRAMs).
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
        return reads[0], reads[1]

    def _phong(self, m, pipe):
        """The ``FRONT`` stages of the per-sample Phong method: dot products, specular
        table, light sums (``PHONG_FRONT`` stages), then delays to the combine."""
        f, e = self.cfg.normal_frac_bits, self.cfg.spec_table_entries
        n = self.i.payload.normal
        spec = Memory(shape=unsigned(ONE_BITS), depth=e + 1, init=[])
        m.submodules.spec = spec
        wr = spec.write_port()
        m.d.comb += [
            wr.addr.eq(self.load.payload.addr),
            wr.data.eq(self.load.payload.data),
            wr.en.eq(self.load.valid),
        ]
        diffuse4, specular4 = [], []
        for k in range(self.lights):
            light, half = self.light[k], self.half[k]
            # Products, then their sums: N.L, N.H.
            pl = [pipe.register(n[a] * light[a], name=f"nl{k}_{a}") for a in range(3)]
            ph = [pipe.register(n[a] * half[a], name=f"nh{k}_{a}") for a in range(3)]
            ndl = pipe.register(sum(pl), name=f"ndl_raw{k}")
            ndh = pipe.register(sum(ph), name=f"ndh_raw{k}")
            # Rounded to UQ1.12 and clamped; the specular table's index.
            ndl = round_shift(ndl, 2 * f - 12, "nearest-up")
            ndh = round_shift(ndh, 2 * f - 12, "nearest-up")
            ndl2 = pipe.register(
                Mux(ndl < 0, 0, Mux(ndl > ONE, ONE, ndl)), name=f"ndl{k}", shape=unsigned(ONE_BITS)
            )
            ndh_c = Mux(ndh < 0, 0, Mux(ndh > ONE, ONE, ndh))
            index = pipe.register(
                round_shift(ndh_c * e, 12, "nearest-up"),
                name=f"spec_index{k}",
                shape=unsigned(bit_length(e)),
            )
            # The table read; the light's coefficients I kd and I ks.
            rd = spec.read_port()
            m.d.comb += [rd.addr.eq(index), rd.en.eq(pipe.advance)]
            ndl3 = pipe.register(ndl2, name=f"ndl3_{k}")
            ikd = pipe.register(self.intensity[k] * self.kd, name=f"ikd{k}")
            iks = pipe.register(self.intensity[k] * self.ks, name=f"iks{k}")
            # The light's terms.
            term = round_shift(ikd * ndl3, 2 * 8, "nearest-up")
            diffuse4.append(pipe.register(term, name=f"diffuse{k}", shape=unsigned(MAP_BITS)))
            term = round_shift(iks * rd.data, 2 * 8, "nearest-up")
            specular4.append(pipe.register(term, name=f"specular{k}", shape=unsigned(MAP_BITS)))
        # Summed over the lights.
        total = unsigned(MAP_BITS + bit_length(self.lights))
        specular5 = pipe.register(sum(specular4), name="specular", shape=total)
        diffuse5 = pipe.register(sum(diffuse4), name="diffuse", shape=total)
        pad = len(FRONT) - PHONG_FRONT
        return (
            pipe.delay(diffuse5, pad, name="diffuse_pad"),
            pipe.delay(specular5, pad, name="specular_pad"),
        )

    def _combine(self, m, pipe, rgb, diffuse, specular):
        """ "products": ``round(ka c / 2**8)``, ``round(diffuse c / 2**12)``; "sum": their
        sum with the specular term, clamped at 1.0."""
        ambient = [round_shift(self.ka * rgb[k], 8, "nearest-up") for k in range(3)]
        lit = [round_shift(diffuse * rgb[k], 12, "nearest-up") for k in range(3)]
        ambient = [pipe.register(ambient[k], name=f"ambient{k}") for k in range(3)]
        lit = [pipe.register(lit[k], name=f"diffuse_lit{k}") for k in range(3)]
        specular = pipe.register(specular, name="specular_lit")
        for k in range(3):
            total = ambient[k] + lit[k] + specular
            out = Mux(total > ONE, ONE, total)
            m.d.comb += self.o.payload.rgb[k].eq(
                pipe.register(out, name=f"lit{k}", shape=unsigned(ONE_BITS))
            )
