"""Gradient unit RTL: central differences -> world scaling -> magnitude and unit normals,
bit-exact with ``models.units.gradient`` (``to_world``, ``magnitude``, ``normals``).

# Ref: architectures.md section 9.1 (central differences on samples); Levoy 1988;
#      models/units/gradient.py.

Hardware split (``LATENCY = 3``, ``II = 1``):

1. differences ``ahead - behind`` per axis (``source = "sample"``; with ``"voxel"`` the
   three interpolated voxel differences enter directly) times the per-axis UQ1.12
   ``ratio`` (``to_world``), rounded nearest-up;
2. ``s0 = |g|^2``; the leading-zero normaliser picks ``shift = max(F + 2 - ceil(bits(s0)
   / 2), 0)`` (``ceil(bits(s0) / 2)`` is the bit length of ``isqrt(s0)``, so no first
   square root is needed); ``m = isqrt(s0 << 2 shift)`` (restoring, one step per bit);
3. three exact dividers ``N = floor((2 (-g << shift) 2**F + m) / 2m)``, clipped to
   ``+-2**F``; the magnitude ``isqrt(s0) = m >> shift``.

Stages 2 and 3 are deep combinational blocks (a square root of ``2 (B + S) + 4`` bits and
three ``F + 1``-step dividers): they meet the model's 3-cycle latency, at the cost of
clock rate; a faster clock would pipeline them over ``~(B + S + F) / 4`` more stages.
"""

from __future__ import annotations

from amaranth import Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In

from models.units import gradient as model
from models.units.gradient import GradientConfig
from rtl.common import StallingPipeline, divide_bounded, isqrt, round_shift, unit_ports

__all__ = ["Gradient", "LATENCY", "II", "input_layout", "output_layout", "RATIO_BITS"]

LATENCY = model.LATENCY
II = model.II
#: ``to_world`` ratios are UQ1.12 (``models.units.gradient._RATIO_BITS``).
RATIO_BITS = 12


def _diff_bits(sample_bits: int) -> int:
    """Signed width of a difference of two unsigned ``sample_bits`` samples (voxel
    differences ``2 (v1 - v0)`` fit the same width plus one)."""
    return sample_bits + 2


def input_layout(cfg: GradientConfig, sample_bits: int):
    """``source = "sample"``: ``ahead[3]``, ``behind[3]`` unsigned samples in ``(x, y,
    z)`` order; ``"voxel"``: ``diff[3]`` signed interpolated voxel differences."""
    if cfg.source == "sample":
        s = unsigned(sample_bits)
        return data.StructLayout(
            {"ahead": data.ArrayLayout(s, 3), "behind": data.ArrayLayout(s, 3)}
        )
    return data.StructLayout({"diff": data.ArrayLayout(signed(_diff_bits(sample_bits)), 3)})


def output_layout(cfg: GradientConfig, sample_bits: int):
    """``normal[3]`` SQ1.F ``(x, y, z)`` and ``magnitude`` (``floor(|g|)``)."""
    f = cfg.normal_frac_bits
    return data.StructLayout(
        {
            "normal": data.ArrayLayout(signed(f + 2), 3),
            "magnitude": unsigned(_diff_bits(sample_bits) + 1),
        }
    )


class Gradient(wiring.Component):
    """Gradient, magnitude and normal unit.

    Parameters
    ----------
    cfg : GradientConfig
        Source (``sample`` / ``voxel``) and normal fraction bits ``F``.
    sample_bits : int
        Width of the interpolated samples (``B + S``).

    Ports
    -----
    i, o : stream
        :func:`input_layout` in, :func:`output_layout` out.
    ratio : In
        ``to_world`` factors ``min(spacing) / spacing`` per axis ``(x, y, z)``, UQ1.12
        (4096 on isotropic data); static during a pass.
    """

    def __init__(self, cfg: GradientConfig | None = None, sample_bits: int = 16):
        cfg = cfg if cfg is not None else GradientConfig()
        self.cfg, self.sample_bits = cfg, sample_bits
        ratio = In(data.ArrayLayout(unsigned(RATIO_BITS + 1), 3))
        ports = unit_ports(input_layout(cfg, sample_bits), output_layout(cfg, sample_bits))
        super().__init__({**ports, "ratio": ratio})

    def elaborate(self, platform):
        m = Module()
        f = self.cfg.normal_frac_bits
        gbits = _diff_bits(self.sample_bits) + 1  # |g| after to_world fits the difference width
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        payload = self.i.payload

        # Stage 1: differences, to_world.
        g = []
        for axis in range(3):
            if self.cfg.source == "sample":
                diff = payload.ahead[axis] - payload.behind[axis]  # signed(B + S + 1)
            else:
                diff = payload.diff[axis]
            scaled = round_shift(diff * self.ratio[axis], RATIO_BITS, "nearest-up")
            g.append(pipe.register(scaled, name=f"g{axis}", shape=signed(gbits)))

        # Stage 2: |g|^2, normaliser shift, square root.
        s0_bits = 2 * gbits + 1
        s0 = Signal(s0_bits, name="s0")
        m.d.comb += s0.eq(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
        s0_len = Signal(range(s0_bits + 1), name="s0_len")
        for b in range(s0_bits):
            with m.If(s0[b]):
                m.d.comb += s0_len.eq(b + 1)
        root_len = (s0_len + 1) >> 1
        shift = Signal(range(f + 3), name="shift")
        m.d.comb += shift.eq(Mux(root_len >= f + 2, 0, (f + 2) - root_len))
        s_bits = max(s0_bits, 2 * (f + 2))
        s = Signal(s_bits, name="s")
        m.d.comb += s.eq(s0 << (shift << 1))
        root = isqrt(m, s, s_bits, name="root")
        gs = [
            pipe.register(g[a] << shift, name=f"gs{a}", shape=signed(gbits + f + 2))
            for a in range(3)
        ]
        m_reg = pipe.register(root, name="m")
        shift_reg = pipe.register(shift, name="shift_reg")
        zero = pipe.register(s0 == 0, name="zero")

        # Stage 3: three exact dividers, rounding half up (floor of (2 num + m) / 2m).
        divisor = m_reg << 1
        limit = 1 << f
        out = self.o.payload
        for a in range(3):
            num = Signal(signed(gbits + 2 * f + 5), name=f"num{a}")
            m.d.comb += num.eq(((-gs[a]) << (f + 1)) + m_reg)
            negative = num < 0
            magnitude = Signal(unsigned(gbits + 2 * f + 5), name=f"abs{a}")
            m.d.comb += magnitude.eq(Mux(negative, -num + divisor - 1, num))
            q = divide_bounded(m, magnitude, divisor, f + 2, name=f"div{a}")
            n = Signal(signed(f + 4), name=f"n{a}")
            m.d.comb += n.eq(Mux(negative, -q, q))
            clipped = Mux(zero, 0, Mux(n > limit, limit, Mux(n < -limit, -limit, n)))
            m.d.comb += out.normal[a].eq(
                pipe.register(clipped, name=f"normal{a}", shape=signed(f + 2))
            )
        m.d.comb += out.magnitude.eq(
            pipe.register(m_reg >> shift_reg, name="magnitude", shape=out.magnitude.shape())
        )
        return m
