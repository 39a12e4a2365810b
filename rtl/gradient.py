"""Gradient unit RTL: central differences -> world scaling -> magnitude and unit normals,
bit-exact with ``models.units.gradient`` (``to_world``, ``magnitude``, ``normals``).

# Ref: architectures.md section 9.1 (central differences on samples); Levoy 1988;
#      models/units/gradient.py.

Stages (``STAGES``; ``LATENCY = 25``, ``II = 1``), each at most ~40 generic gates deep
(the clock of a 125 MHz machine at 0.35 um by hwsim.energy.synth's estimate):

1. ``difference``: ``ahead - behind`` per axis (``source = "sample"``; with ``"voxel"``
   the three interpolated voxel differences enter directly);
2. ``to_world``: times the per-axis UQ1.12 ``ratio``, rounded nearest-up;
3. ``square``, 4. ``sum``: ``s0 = |g|^2``;
5. ``normalise``: ``shift = max(F + 2 - ceil(bits(s0) / 2), 0)`` (``ceil(bits(s0) / 2)``
   is the bit length of ``isqrt(s0)``, so no first square root is needed), as the count
   of the zero tests ``s0 < 4**(F + 2 - j)``; ``s = s0 << 2 shift``;
6-17. ``sqrt``: ``m = isqrt(s)``, restoring, its ``(bits(s) + 1) / 2`` steps spread over
   ``SQRT_STAGES = 12`` stages (two per stage at the default and at 16-bit voxels);
18. ``numerator``: ``num = m - (g << shift) 2**(F + 1)`` and its magnitude (``2m + ~num``
   when negative, for a quotient rounded half up);
19-24. ``divide``: three exact dividers ``floor(|num| / 2m)``, ``F + 2`` steps over
   ``DIVIDE_STAGES = 6`` stages;
25. ``sign``: the quotient's sign, clipped to ``+-2**F``; the magnitude ``isqrt(s0) = m
   >> shift``.
"""

from __future__ import annotations

from amaranth import Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In

from models.units.gradient import GradientConfig
from rtl.common import StallingPipeline, divide_bounded, isqrt, round_shift, unit_ports

__all__ = ["Gradient", "LATENCY", "II", "input_layout", "output_layout", "RATIO_BITS"]

#: Restoring square-root and divider steps are spread over these many stages.
SQRT_STAGES = 12
DIVIDE_STAGES = 6
#: The stage plan: one name per register stage (``LATENCY`` is its length, the RTL's own;
#: ``models.units.gradient.LATENCY`` must equal it, as tests/rtl/test_gradient.py checks).
STAGES = (
    "difference",
    "to_world",
    "square",
    "sum",
    "normalise",
    *("sqrt",) * SQRT_STAGES,
    "numerator",
    *("divide",) * DIVIDE_STAGES,
    "sign",
)
LATENCY = len(STAGES)
II = 1
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

        # "difference": ahead - behind per axis.
        diffs = []
        for axis in range(3):
            if self.cfg.source == "sample":
                diff = payload.ahead[axis] - payload.behind[axis]  # signed(B + S + 1)
            else:
                diff = payload.diff[axis]
            diffs.append(pipe.register(diff, name=f"d{axis}"))
        # "to_world": times the UQ1.12 ratio, rounded nearest-up.
        g = []
        for axis in range(3):
            scaled = round_shift(diffs[axis] * self.ratio[axis], RATIO_BITS, "nearest-up")
            g.append(pipe.register(scaled, name=f"g{axis}", shape=signed(gbits)))

        # "square", "sum": s0 = |g|^2.
        s0_bits = 2 * gbits + 1
        squares = [pipe.register(g[a] * g[a], name=f"sq{a}", shape=2 * gbits) for a in range(3)]
        s0 = pipe.register(squares[0] + squares[1] + squares[2], name="s0", shape=s0_bits)
        g2 = [pipe.delay(g[a], 2, name=f"g2_{a}") for a in range(3)]

        # "normalise": the leading-zero shift, s = s0 << 2 shift.
        # shift = max(F + 2 - ceil(bits(s0) / 2), 0) = #{j in 1..F+2: s0 < 4**(F + 2 - j)}
        # (a thermometer code of zero tests, summed: no priority chain).
        zeros = [
            s0[2 * (f + 2 - j) :] == 0 if 2 * (f + 2 - j) < s0_bits else Const(1, 1)
            for j in range(1, f + 3)
        ]
        shift = Signal(range(f + 3), name="shift")
        m.d.comb += shift.eq(sum(zeros))
        s_bits = max(s0_bits, 2 * (f + 2))
        s = pipe.register(s0 << (shift << 1), name="s", shape=s_bits)
        gs = [
            pipe.register(g2[a] << shift, name=f"gs{a}", shape=signed(gbits + f + 2))
            for a in range(3)
        ]
        shift_reg = pipe.register(shift, name="shift_reg")
        zero = pipe.register(s0 == 0, name="zero")

        # "sqrt" x SQRT_STAGES: m = isqrt(s), restoring, its steps spread over the stages.
        root = isqrt(m, s, s_bits, name="root", pipe=pipe, stages=SQRT_STAGES)
        m_reg = pipe.register(root, name="m")
        gs = [pipe.delay(gs[a], SQRT_STAGES, name=f"gs_sqrt{a}") for a in range(3)]
        shift_reg = pipe.delay(shift_reg, SQRT_STAGES, name="shift_sqrt")
        zero = pipe.delay(zero, SQRT_STAGES, name="zero_sqrt")

        # "numerator": |2 (-g << shift) 2**F + m| and its sign, for floor((2 num + m) / 2m).
        divisor = m_reg << 1
        nbits = gbits + 2 * f + 5
        magnitudes, negatives = [], []
        for a in range(3):
            num = Signal(signed(nbits), name=f"num{a}")
            m.d.comb += num.eq(m_reg - (gs[a] << (f + 1)))
            negative = num < 0
            magnitude = Mux(negative, divisor + ~num, num)  # ~num = -num - 1
            magnitudes.append(pipe.register(magnitude, name=f"abs{a}", shape=unsigned(nbits)))
            negatives.append(pipe.register(negative, name=f"neg{a}"))
        divisor = pipe.register(divisor, name="divisor")
        m_reg = pipe.register(m_reg, name="m_num")
        shift_reg = pipe.register(shift_reg, name="shift_num")
        zero = pipe.register(zero, name="zero_num")

        # "divide" x DIVIDE_STAGES: three exact dividers; then the sign and clip.
        limit = 1 << f
        out = self.o.payload
        for a in range(3):
            q = divide_bounded(
                m, magnitudes[a], divisor, f + 2, name=f"div{a}", pipe=pipe, stages=DIVIDE_STAGES
            )
            qs = pipe.register(q, name=f"q{a}")
            negative = pipe.delay(negatives[a], DIVIDE_STAGES, name=f"neg_div{a}")
            n = Signal(signed(f + 4), name=f"n{a}")
            m.d.comb += n.eq(Mux(negative, -qs, qs))
            zero_a = pipe.delay(zero, DIVIDE_STAGES, name=f"zero_div{a}")
            clipped = Mux(zero_a, 0, Mux(n > limit, limit, Mux(n < -limit, -limit, n)))
            m.d.comb += out.normal[a].eq(
                pipe.register(clipped, name=f"normal{a}", shape=signed(f + 2))
            )
        magnitude = pipe.delay(m_reg >> shift_reg, DIVIDE_STAGES, name="magnitude")
        m.d.comb += out.magnitude.eq(
            pipe.register(magnitude, name="magnitude", shape=out.magnitude.shape())
        )
        return m
