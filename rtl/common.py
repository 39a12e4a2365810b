"""Shared RTL building blocks: the stalling pipeline, rounding shifts, exact integer square
root and division, and constant division by a reciprocal multiply.

# Ref: hwsim.numerics.round_shift (the rounding modes these shifts implement bit for bit);
#      Granlund & Montgomery 1994, "Division by invariant integers using multiplication".

Every unit is a pipeline of ``LATENCY`` register stages that advance together
(``advance = ~out.valid | out.ready``): with the output accepted, it takes one payload per
cycle (II = 1); with the output refused, every stage holds and ``in.ready`` drops, so
nothing is lost.  A unit's ``LATENCY`` is the length of its own stage plan (``STAGES``:
one name per register stage, in the unit's module), not its model's constant; the unit
tests measure the handshake latency in simulation and compare it with the model's.
The square root and the dividers take ``stages`` to spread their steps over that many
register stages (``pipe.register`` between groups of steps), so a deep block meets the
clock at the cost of latency.  ``in.ready`` is a combinational function of ``out.ready`` (no skid
buffer): a pipeline top that chains units sees one ready path through them.
"""

from __future__ import annotations

from amaranth import Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.hdl import Value
from amaranth.lib import stream
from amaranth.lib.wiring import In, Out

__all__ = [
    "StallingPipeline",
    "step_groups",
    "load_port",
    "unit_ports",
    "round_shift",
    "isqrt",
    "divide_bounded",
    "divide_by_constant",
    "clamp",
    "bit_length",
]


def unit_ports(in_layout, out_layout, **ports) -> dict:
    """The signature members of a pipelined unit: stream ``i`` of ``in_layout`` in, stream
    ``o`` of ``out_layout`` out, and ``ports`` (statics, load ports) as given."""
    return {"i": In(stream.Signature(in_layout)), "o": Out(stream.Signature(out_layout)), **ports}


def load_port(layout) -> In:
    """A table-load port: a stream the unit always accepts (no back-pressure)."""
    return In(stream.Signature(layout, always_ready=True))


def bit_length(n: int) -> int:
    """Bits of a non-negative Python integer (at least 1)."""
    return max(int(n).bit_length(), 1)


class StallingPipeline:
    """``latency`` register stages between ``i`` and ``o`` that advance together.

    Parameters
    ----------
    m : Module
    i, o : stream.Interface
        The unit's input and output streams (``o.payload`` is driven by the caller from
        the last stage).
    latency : int
        Register stages from input handshake to output valid (>= 1).
    """

    def __init__(self, m: Module, i: stream.Interface, o: stream.Interface, latency: int):
        if latency < 1:
            raise ValueError("latency must be >= 1")
        self.m = m
        self.advance = Signal(name="advance")
        self.valid = [Signal(name=f"valid_{k}") for k in range(latency)]
        m.d.comb += [
            self.advance.eq(~self.valid[-1] | o.ready),
            i.ready.eq(self.advance),
            o.valid.eq(self.valid[-1]),
        ]
        with m.If(self.advance):
            m.d.sync += self.valid[0].eq(i.valid)
            for k in range(1, latency):
                m.d.sync += self.valid[k].eq(self.valid[k - 1])

    def register(self, value, *, name: str, shape=None) -> Signal:
        """A stage register loaded with ``value`` whenever the pipeline advances."""
        value = Value.cast(value)
        reg = Signal(shape if shape is not None else value.shape(), name=name)
        with self.m.If(self.advance):
            self.m.d.sync += reg.eq(value)
        return reg

    def delay(self, value, stages: int, *, name: str, shape=None) -> Value:
        """``value`` carried through ``stages`` stage registers (0: ``value`` itself)."""
        for k in range(stages):
            value = self.register(value, name=f"{name}_d{k}", shape=shape)
        return value


def step_groups(steps: int, stages: int) -> list[int]:
    """``steps`` iterations split over ``stages`` register stages, as evenly as possible
    (the larger groups first: a restoring step's width only grows; with fewer steps than
    stages the last groups are empty, their stages plain registers)."""
    if stages < 1:
        raise ValueError(f"{stages} stages: at least one")
    base, extra = divmod(steps, stages)
    return [base + (k < extra) for k in range(stages)]


def round_shift(value, shift: int, rounding: str) -> Value:
    """``value / 2**shift`` with ``rounding`` (``shift <= 0`` multiplies), exactly as
    :func:`hwsim.numerics.round_shift` on the same integers."""
    value = Value.cast(value)
    if shift <= 0:
        return value << (-shift)
    if rounding == "floor":
        return value >> shift
    if rounding == "nearest-up":
        return (value + (1 << (shift - 1))) >> shift
    floor = value >> shift
    rem = value[:shift]
    if rounding == "truncate":
        negative = value[-1] if value.shape().signed else Const(0, 1)
        return floor + (negative & (rem != 0))
    if rounding == "nearest-even":
        half = 1 << (shift - 1)
        return floor + ((rem > half) | ((rem == half) & floor[0]))
    raise ValueError(f"unknown rounding {rounding!r}")


def clamp(m: Module, value, lo: int, hi: int, *, name: str) -> Signal:
    """``min(max(value, lo), hi)`` as a signal wide enough for ``[lo, hi]``."""
    shape = signed(max(bit_length(hi), bit_length(-lo)) + 1) if lo < 0 else unsigned(bit_length(hi))
    out = Signal(shape, name=name)
    m.d.comb += out.eq(Mux(value < lo, lo, Mux(value > hi, hi, value)))
    return out


def isqrt(
    m: Module, value, width: int, *, name: str, pipe: StallingPipeline | None = None, stages=1
) -> Signal:
    """``floor(sqrt(value))`` of an unsigned ``width``-bit value, one restoring step per
    result bit, unrolled.  With ``stages > 1`` the steps are split over that many pipeline
    stages (:func:`step_groups`): the remainder, the partial root and the input bits not
    yet consumed are registered in ``pipe`` between groups (``stages - 1`` registers; the
    result is combinational after the last group, for the caller's stage register)."""
    value = Value.cast(value).as_unsigned()
    rbits = (width + 1) // 2
    rem = Const(0, rbits + 2)
    root = Const(0, rbits)
    k = rbits
    for g, size in enumerate(step_groups(rbits, stages)):
        if g:
            done = rbits - k  # root bits so far; the remainder is below 2 root + 1
            rem = pipe.register(rem[: done + 2], name=f"{name}_rem_s{g}")
            root = pipe.register(root[:done], name=f"{name}_root_s{g}")
            value = pipe.register(value[: min(2 * k, width)], name=f"{name}_in_s{g}")
        for _ in range(size):
            k -= 1
            pair = value[2 * k : 2 * k + 2] if 2 * k < width else Const(0, 2)
            shifted = Signal(rbits + 3, name=f"{name}_r{k}")
            m.d.comb += shifted.eq((rem << 2) | pair)
            trial = (root << 2) | 1
            ge = shifted >= trial
            next_rem = Signal(rbits + 2, name=f"{name}_rem{k}")
            next_root = Signal(rbits, name=f"{name}_root{k}")
            m.d.comb += [
                next_rem.eq(Mux(ge, shifted - trial, shifted)),
                next_root.eq((root << 1) | ge),
            ]
            rem, root = next_rem, next_root
    out = Signal(rbits, name=name)
    m.d.comb += out.eq(root)
    return out


def divide_bounded(
    m: Module,
    numerator,
    divisor,
    quotient_bits: int,
    *,
    name: str,
    pipe: StallingPipeline | None = None,
    stages: int = 1,
) -> Signal:
    """``floor(numerator / divisor)`` of unsigned values known to satisfy
    ``numerator < divisor * 2**quotient_bits`` (restoring division, unrolled, one step
    per quotient bit).  A zero divisor gives an all-ones quotient.  With ``stages > 1``
    the steps are split over that many pipeline stages as :func:`isqrt`'s (remainder,
    quotient bits so far, divisor and the numerator bits not yet consumed registered)."""
    numerator, divisor = Value.cast(numerator).as_unsigned(), Value.cast(divisor)
    dbits = divisor.shape().width
    rem = Signal(dbits + 1, name=f"{name}_rem_init")
    m.d.comb += rem.eq(numerator >> quotient_bits)
    bits = []
    k = quotient_bits
    for g, size in enumerate(step_groups(quotient_bits, stages)):
        if g:
            rem = pipe.register(rem, name=f"{name}_rem_s{g}")
            divisor = pipe.register(divisor, name=f"{name}_div_s{g}")
            numerator = pipe.register(numerator[:k], name=f"{name}_num_s{g}")
            bits = [pipe.register(b, name=f"{name}_q_s{g}_{j}") for j, b in enumerate(bits)]
        for _ in range(size):
            k -= 1
            shifted = Signal(dbits + 2, name=f"{name}_s{k}")
            m.d.comb += shifted.eq((rem << 1) | numerator[k])
            ge = Signal(name=f"{name}_q{k}")
            m.d.comb += ge.eq(shifted >= divisor)
            next_rem = Signal(dbits + 1, name=f"{name}_rem{k}")
            m.d.comb += next_rem.eq(Mux(ge, shifted - divisor, shifted))
            bits.append(ge)
            rem = next_rem
    out = Signal(quotient_bits, name=name)
    m.d.comb += out.eq(Cat(*bits[::-1]))
    return out


def divide_by_constant(value, divisor: int, value_bits: int) -> Value:
    """``floor(value / divisor)`` of an unsigned ``value_bits``-bit value by a reciprocal
    multiply: ``(value * ceil(2**k / d)) >> k`` with ``k = value_bits + ceil(log2 d)``,
    exact for every value below ``2**value_bits`` (Granlund & Montgomery, theorem 4.2)."""
    if divisor < 1:
        raise ValueError("divisor must be >= 1")
    value = Value.cast(value)
    if divisor & (divisor - 1) == 0:
        return value >> (divisor.bit_length() - 1)
    k = value_bits + (divisor - 1).bit_length()
    magic = -(-(1 << k) // divisor)
    return (value * magic) >> k
