"""Compositor RTL: opacity correction, front-to-back blending with the early-termination
flag, and maximum-intensity projection; bit-exact with ``models.units.composite``
(``correct_opacity``, ``front_to_back``, ``terminated``, ``mip``).

# Ref: architectures.md sections 3, 4 (ERT threshold), 6.5 (opacity correction), 9.1 and
#      9.3 (compositor: table 1 + multiply 1 + accumulate 1); models/units/composite.py.

The unit is a read-modify-write datapath: a sample enters with its ray's partial
accumulators (from the ray buffer that the pipeline top keeps) and leaves with the
updated ones, so consecutive samples may belong to different rays (slice order).
Stages (``LATENCY = 3``, ``II = 1``):

1. opacity correction ``a' = table[min(a, 4096)]`` (synchronous SRAM of 4097 UQ1.12
   entries, written through ``load``; the identity table is ``k = 1``); colours clamp
   at 1.0; ``mip' = max(mip, sample)``;
2. ``w = round((1 - A) a' / 2**12)`` (UQ1.F, nearest-up);
3. ``C += round(w c / 2**12)``, ``A += w``, each saturated at 1.0;
   ``terminated = ert_enable & (A >= ert_threshold)``.

Accumulators entering must lie in ``[0, 1]`` (``2**F``): the unit's own outputs always do.
"""

from __future__ import annotations

from amaranth import Module, Mux, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In

from models.units import composite as model
from models.units.composite import CompositeConfig
from rtl.common import StallingPipeline, load_port, round_shift, unit_ports

__all__ = ["Composite", "LATENCY", "II", "input_layout", "output_layout", "load_layout"]

#: The stage plan: one name per register stage (``LATENCY`` is its length, the RTL's own;
#: ``models.units.composite.LATENCY`` must equal it, as the unit tests check).
STAGES = ("correct", "weight", "products", "accumulate")
LATENCY = len(STAGES)
II = 1
ALPHA_BITS = 12
ONE_A = 1 << ALPHA_BITS
TABLE_ENTRIES = ONE_A + 1


def input_layout(cfg: CompositeConfig, sample_bits: int):
    """``acc[4]`` (premultiplied R, G, B and A, UQ1.F), ``rgb[3]`` and ``alpha`` (UQ1.12,
    13 bits: values above 1.0 saturate), ``mip`` and ``sample`` (raw ``B + S`` bits)."""
    acc = unsigned(cfg.acc.width)  # composite.acc UQ1.F
    one = unsigned(model.ALPHA.width)  # composite.alpha UQ1.12
    return data.StructLayout(
        {
            "acc": data.ArrayLayout(acc, 4),
            "rgb": data.ArrayLayout(one, 3),
            "alpha": one,
            "mip": unsigned(sample_bits),
            "sample": unsigned(sample_bits),
        }
    )


def output_layout(cfg: CompositeConfig, sample_bits: int):
    """Updated ``acc[4]``, ``mip``, and the ``terminated`` flag."""
    return data.StructLayout(
        {
            "acc": data.ArrayLayout(unsigned(cfg.acc.width), 4),
            "mip": unsigned(sample_bits),
            "terminated": unsigned(1),
        }
    )


def load_layout():
    """Opacity-correction table write: ``addr`` 0..4096, ``data`` UQ1.12."""
    return data.StructLayout({"addr": unsigned(ALPHA_BITS + 1), "data": unsigned(ALPHA_BITS + 1)})


class Composite(wiring.Component):
    """Front-to-back compositor with ERT flag and MIP.

    Parameters
    ----------
    cfg : CompositeConfig
        Accumulator fraction bits ``F``.
    sample_bits : int
        Width of raw samples for MIP (``B + S``).

    Ports
    -----
    i, o : stream
        :func:`input_layout` in, :func:`output_layout` out.
    load : In stream, always ready
        Opacity-correction table writes (:func:`models.units.composite.correction_table`).
    ert_threshold : In(F + 1)
        Termination threshold, UQ1.F (``cfg.acc.quantize(threshold)``).
    ert_enable : In(1)
        0 when the threshold is >= 1.0 (ERT off).
    """

    def __init__(self, cfg: CompositeConfig | None = None, sample_bits: int = 16):
        cfg = cfg if cfg is not None else CompositeConfig()
        self.cfg, self.sample_bits = cfg, sample_bits
        ports = unit_ports(
            input_layout(cfg, sample_bits),
            output_layout(cfg, sample_bits),
            load=load_port(load_layout()),
            ert_threshold=In(cfg.acc_frac_bits + 1),
            ert_enable=In(1),
        )
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        frac = self.cfg.acc_frac_bits
        one = 1 << frac
        acc_shape = unsigned(frac + 1)
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        payload = self.i.payload

        # "correct": opacity-correction table, colour saturation, MIP.
        m.submodules.correction = table = Memory(
            shape=unsigned(ALPHA_BITS + 1), depth=TABLE_ENTRIES, init=[]
        )
        wr = table.write_port()
        m.d.comb += [
            wr.addr.eq(self.load.payload.addr),
            wr.data.eq(self.load.payload.data),
            wr.en.eq(self.load.valid),
        ]
        rd = table.read_port()
        m.d.comb += [
            rd.addr.eq(Mux(payload.alpha > ONE_A, ONE_A, payload.alpha)),
            rd.en.eq(pipe.advance),
        ]
        acc1 = [pipe.register(payload.acc[k], name=f"acc1_{k}") for k in range(4)]
        transparency = pipe.register(one - payload.acc[3], name="transparency", shape=acc_shape)
        rgb1 = [
            pipe.register(
                Mux(payload.rgb[k] > ONE_A, ONE_A, payload.rgb[k]),
                name=f"rgb1_{k}",
                shape=unsigned(ALPHA_BITS + 1),
            )
            for k in range(3)
        ]
        mip1 = pipe.register(
            Mux(payload.sample > payload.mip, payload.sample, payload.mip), name="mip1"
        )

        # "weight": w = round((1 - A) a').
        w = round_shift(transparency * rd.data, ALPHA_BITS, "nearest-up")
        w2 = pipe.register(w, name="w2", shape=acc_shape)
        acc2 = [pipe.register(acc1[k], name=f"acc2_{k}") for k in range(4)]
        rgb2 = [pipe.register(rgb1[k], name=f"rgb2_{k}") for k in range(3)]
        mip2 = pipe.register(mip1, name="mip2")

        # "products": round(w c / 2**12).
        products = [
            pipe.register(round_shift(w2 * rgb2[k], ALPHA_BITS, "nearest-up"), name=f"wc{k}")
            for k in range(3)
        ]
        w3 = pipe.register(w2, name="w3")
        acc3 = [pipe.register(acc2[k], name=f"acc3_{k}") for k in range(4)]
        mip3 = pipe.register(mip2, name="mip3")

        # "accumulate": C += w c, A += w, each saturated at 1.0; the termination flag.
        out = self.o.payload
        new = [acc3[k] + products[k] for k in range(3)]
        new.append(acc3[3] + w3)
        for k in range(4):
            value = Mux(new[k] > one, one, new[k])
            m.d.comb += out.acc[k].eq(pipe.register(value, name=f"acc4_{k}", shape=acc_shape))
        # min(A, 1) >= threshold, as two compares side by side.
        reachable = self.ert_threshold <= one
        stop = self.ert_enable & reachable & (new[3] >= self.ert_threshold)
        m.d.comb += [
            out.terminated.eq(pipe.register(stop, name="terminated")),
            out.mip.eq(pipe.register(mip3, name="mip4")),
        ]
        return m
