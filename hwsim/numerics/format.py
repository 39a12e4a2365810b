"""Fixed-point formats: signedness, integer and fraction bits, rounding and overflow rule.

# Ref: design.md section 5 (every datapath value has a named format, rounding mode and
#      overflow rule; no NaN, no silent wrap).

A value is held as an ``int64`` *raw* integer; its real value is ``raw * 2**-frac_bits``.
Overflow is ``saturate`` (clamp to the representable range and count it) or ``error``
(raise); there is no silent wrap.  Rounding modes, applied whenever fraction bits are
dropped:

``nearest-up``   round to nearest, ties toward +inf (``floor(x + 1/2)``: one adder)
``nearest-even`` round to nearest, ties to even
``truncate``     toward zero
``floor``        toward -inf (an arithmetic right shift)
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ROUNDINGS",
    "OVERFLOWS",
    "FixedFormat",
    "OverflowError_",
    "SaturationLog",
    "round_shift",
    "round_shift_raw",
    "round_scaled",
    "ROUNDING_CODES",
    "rescale",
    "mul",
    "SATURATIONS",
    "sq",
    "uq",
]

ROUNDINGS = ("nearest-up", "nearest-even", "truncate", "floor")
#: Integer code of each rounding mode, for :func:`round_shift_raw` and
#: :func:`round_scaled` (plain integers, so compiled kernels can take them).
ROUNDING_CODES = {"floor": 0, "nearest-up": 1, "truncate": 2, "nearest-even": 3}
OVERFLOWS = ("saturate", "error")


class OverflowError_(ArithmeticError):
    """A value left its format whose overflow rule is ``error``."""


class SaturationLog(Counter):
    """How many values each named format clipped (format name -> count)."""


#: The process-wide log units add to; renderers reset and read it per run.
SATURATIONS = SaturationLog()


@dataclass(frozen=True, kw_only=True)
class FixedFormat:
    """A named fixed-point format.

    Parameters
    ----------
    name : str
        What the value is (``"interp.weight"``); used in saturation logs and docs.
    signed : bool
        Two's complement with one sign bit beyond ``int_bits``.
    int_bits, frac_bits : int
        Integer and fraction bits (``frac_bits`` may be 0; ``int_bits`` may be 0).
    rounding : str
        One of :data:`ROUNDINGS`, used when this format receives a finer value.
    overflow : str
        One of :data:`OVERFLOWS`.
    """

    name: str
    signed: bool
    int_bits: int
    frac_bits: int
    rounding: str = "nearest-up"
    overflow: str = "saturate"

    def __post_init__(self) -> None:
        if self.int_bits < 0 or self.frac_bits < 0 or self.width < 1 or self.width > 62:
            raise ValueError(f"{self.name}: bad widths {self.int_bits}.{self.frac_bits}")
        if self.rounding not in ROUNDINGS or self.overflow not in OVERFLOWS:
            raise ValueError(f"{self.name}: bad rounding/overflow {self.rounding}/{self.overflow}")

    @property
    def width(self) -> int:
        """Total bits, sign included."""
        return int(self.signed) + self.int_bits + self.frac_bits

    @property
    def raw_min(self) -> int:
        return -(1 << (self.int_bits + self.frac_bits)) if self.signed else 0

    @property
    def raw_max(self) -> int:
        return (1 << (self.int_bits + self.frac_bits)) - 1

    @property
    def lsb(self) -> float:
        """Value of one raw step."""
        return 2.0**-self.frac_bits

    @property
    def min_value(self) -> float:
        return self.raw_min * self.lsb

    @property
    def max_value(self) -> float:
        return self.raw_max * self.lsb

    def describe(self) -> str:
        """E.g. ``"u4.8 nearest-up saturate"`` (``s`` for signed)."""
        kind = "s" if self.signed else "u"
        return f"{kind}{self.int_bits}.{self.frac_bits} {self.rounding} {self.overflow}"

    def saturate(self, raw: np.ndarray) -> np.ndarray:
        """Apply the overflow rule to raw integers (count or raise)."""
        raw = np.asarray(raw, dtype=np.int64)
        if raw.size == 0 or (self.raw_min <= raw.min() and raw.max() <= self.raw_max):
            return raw  # the common case: two reductions, no copies
        low, high = raw < self.raw_min, raw > self.raw_max
        clipped = int(np.count_nonzero(low) + np.count_nonzero(high))
        if clipped:
            if self.overflow == "error":
                raise OverflowError_(
                    f"{self.name} ({self.describe()}): {clipped} values out of "
                    f"range {self.min_value:g} .. {self.max_value:g}"
                )
            SATURATIONS[self.name] += clipped
            raw = np.clip(raw, self.raw_min, self.raw_max)
        return raw

    def quantize(self, x: np.ndarray) -> np.ndarray:
        """Real values to raw integers with this format's rounding and overflow rule.

        NaN or Inf input raises ``ValueError``: nothing downstream may see it.
        """
        x = np.asarray(x, dtype=np.float64)
        scaled = x * (2.0**self.frac_bits)
        inside = True
        if x.size:
            # NaN and Inf show in the extremes, so two reductions check everything.
            lo, hi = x.min(), x.max()
            if not (np.isfinite(lo) and np.isfinite(hi)):
                raise ValueError(f"{self.name}: NaN or Inf cannot be quantised")
            limit = 2.0**62
            if not -limit <= lo * 2.0**self.frac_bits <= hi * 2.0**self.frac_bits <= limit:
                scaled = np.clip(scaled, -limit, limit)
            # Every rounding mode is monotone: when the extremes land inside the format,
            # every value does, and the overflow rule has nothing to check.
            ends = self._round(np.array([lo, hi]) * 2.0**self.frac_bits)
            inside = self.raw_min <= ends[0] and ends[1] <= self.raw_max
        raw = self._round(scaled).astype(np.int64)
        return raw if inside else self.saturate(raw)

    def _round(self, scaled: np.ndarray) -> np.ndarray:
        """Scaled reals to integral float64 with this format's rounding."""
        return round_scaled(scaled, ROUNDING_CODES[self.rounding])

    def to_float(self, raw: np.ndarray) -> np.ndarray:
        """Raw integers to their real values (float64, exact for widths <= 53)."""
        return np.asarray(raw, dtype=np.float64) * self.lsb


def round_shift(
    raw: np.ndarray, shift: int, rounding: str, *, keep_dtype: bool = False
) -> np.ndarray:
    """Divide raw integers by ``2**shift`` with ``rounding`` (``shift <= 0`` multiplies).

    The result is int64, or, with ``keep_dtype``, the input's integer type (the caller
    guarantees that the values and the rounding addend fit it, e.g. int32 lerps).
    """
    raw = np.asarray(raw) if keep_dtype else np.asarray(raw, dtype=np.int64)
    return round_shift_raw(raw, shift, ROUNDING_CODES[rounding])


# The two functions below are the arithmetic of every rounding in the datapath, written
# once in a form that runs both on NumPy integer arrays (the vectorised units) and on
# integer scalars inside compiled kernels (models/fused.py registers them with numba):
# plain operators only, no dtype conversions, no array-only calls.


def round_shift_raw(raw, shift: int, code: int):
    """:func:`round_shift` of an integer array or scalar ``raw`` (its own type kept), the
    rounding given by its :data:`ROUNDING_CODES` code."""
    if shift <= 0:
        return raw << (-shift)
    if code == 0:  # floor
        return raw >> shift
    half = 1 << (shift - 1)  # a Python int: keeps an array's dtype
    if code == 1:  # nearest-up
        return (raw + half) >> shift
    floor = raw >> shift
    rem = raw - (floor << shift)
    if code == 2:  # truncate: a negative value with a remainder goes up
        return floor + ((raw < 0) & (rem != 0))
    # nearest-even
    return floor + ((rem > half) | ((rem == half) & ((floor & 1) == 1)))


def round_scaled(scaled, code: int):
    """Scaled reals (array or scalar) to integral float64 with the rounding of ``code``."""
    if code == 1:
        return np.floor(scaled + 0.5)
    if code == 3:
        return np.round(scaled)
    if code == 2:
        return np.trunc(scaled)
    return np.floor(scaled)


def rescale(raw: np.ndarray, src: FixedFormat, dst: FixedFormat) -> np.ndarray:
    """Re-express ``raw`` of ``src`` in ``dst``: shift with ``dst``'s rounding, then its
    overflow rule."""
    return dst.saturate(round_shift(raw, src.frac_bits - dst.frac_bits, dst.rounding))


def mul(
    a: np.ndarray, fa: FixedFormat, b: np.ndarray, fb: FixedFormat, out: FixedFormat
) -> np.ndarray:
    """Exact product of two raw arrays, rounded and saturated into ``out``."""
    prod = np.asarray(a, dtype=np.int64) * np.asarray(b, dtype=np.int64)
    return out.saturate(
        round_shift(prod, fa.frac_bits + fb.frac_bits - out.frac_bits, out.rounding)
    )


def uq(name: str, int_bits: int, frac_bits: int, **rules: str) -> FixedFormat:
    """The unsigned format ``UQint.frac`` named ``name`` (``rules``: rounding, overflow)."""
    return FixedFormat(name=name, signed=False, int_bits=int_bits, frac_bits=frac_bits, **rules)


def sq(name: str, int_bits: int, frac_bits: int, **rules: str) -> FixedFormat:
    """The two's-complement format ``SQint.frac`` named ``name``."""
    return FixedFormat(name=name, signed=True, int_bits=int_bits, frac_bits=frac_bits, **rules)
