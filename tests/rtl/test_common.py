"""The shared RTL arithmetic (rounding shifts, square root, dividers, reciprocal
multiplies) against exact integer references, exhaustively on small widths."""

import math

import numpy as np
import pytest
from amaranth import Module, Signal, signed, unsigned
from amaranth.sim import Simulator

from hwsim.numerics import ROUNDINGS
from hwsim.numerics import round_shift as model_round_shift
from rtl.common import divide_bounded, divide_by_constant, isqrt, round_shift

pytestmark = pytest.mark.rtl


def _evaluate(m, inputs, output, values):
    """Settle the combinational ``output`` for every tuple of ``values``."""
    got = []

    async def bench(ctx):
        for row in values:
            for sig, v in zip(inputs, row, strict=True):
                ctx.set(sig, int(v))
            got.append(ctx.get(output))

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()
    return np.array(got, dtype=np.int64)


@pytest.mark.parametrize("rounding", ROUNDINGS)
@pytest.mark.parametrize("shift", [-2, 0, 1, 3])
def test_round_shift_equals_numerics(rounding, shift):
    m = Module()
    x = Signal(signed(9))
    out = Signal(signed(12))
    m.d.comb += out.eq(round_shift(x, shift, rounding))
    values = np.arange(-256, 256)
    got = _evaluate(m, [x], out, values[:, None])
    assert np.array_equal(got, model_round_shift(values, shift, rounding))


def test_isqrt_is_exact_on_every_10_bit_value():
    m = Module()
    x = Signal(10)
    out = isqrt(m, x, 10, name="root")
    values = np.arange(1024)
    got = _evaluate(m, [x], out, values[:, None])
    assert np.array_equal(got, [math.isqrt(int(v)) for v in values])


def test_bounded_division_is_exact():
    m = Module()
    n, d = Signal(9), Signal(5)
    out = divide_bounded(m, n, d, 5, name="q")
    rows = [(a, b) for b in range(1, 32) for a in range(0, min(512, b * 32))]
    got = _evaluate(m, [n, d], out, rows)
    assert np.array_equal(got, [a // b for a, b in rows])


@pytest.mark.parametrize("divisor", [3, 255, 510, 4095, 8190])
def test_division_by_a_constant_is_exact_over_its_whole_range(divisor):
    m = Module()
    x = Signal(unsigned(14))
    out = Signal(14)
    m.d.comb += out.eq(divide_by_constant(x, divisor, 14))
    values = np.arange(1 << 14)
    got = _evaluate(m, [x], out, values[:, None])
    assert np.array_equal(got, values // divisor)
