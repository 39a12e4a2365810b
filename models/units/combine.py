"""Multi-LUT classification: up to four lookup tables merged by three combination ALUs.

# Ref: architectures.md section 4 (VolumePro 1000, VLI 3.0 vli.h: up to 4 LUTs, 3
#      combination ALUs = two leaf combiners + a final one; opcodes logic, clamped
#      add/sub, min/max, x1/2/4/8 products, final-only multiplies; only one leaf may use
#      a 4096-entry LUT; LUT sizes 4096 or 256; RGB 8-bit, alpha 12-bit).

Tree (fixed wiring)::

    lut0 --+                 lut2 --+
           leaf0 --+         lut3 --+ leaf1
                   +--- final ---+
                          |
                 RGBA -> expand to UQ1.12 -> rest of the pipeline

A missing LUT input reads as 0 (transparent black).  With one LUT the ALUs are bypassed.

Every ALU works per channel on the values *as stored* (format ``combine.rgb``: unorm
``color_bits``, ``combine.alpha``: unorm ``alpha_bits``; full scale ``F = 2**n - 1`` means
1.0), with one opcode for the three colour channels and one for alpha.  Opcodes (the
documented subset; ``a`` is the first operand, ``b`` the second)::

    a, b            pass one operand
    and, or, xor    bitwise on the stored n-bit values
    add             min(a + b, F)                         clamped
    sub, rsub       max(a - b, 0), max(b - a, 0)          clamped
    min, max
    mul, mul2, mul4, mul8
                    min(k * round(a b / F), F), k = 1, 2, 4, 8   (round half up)
    mul_b_alpha     round(a * b_alpha / F_alpha)          final ALU only: every channel of
                                                          a weighted by b's opacity

The opcode categories are vli.h's [V]; the names, the exact subset, the choice of
``mul_b_alpha`` as the final-only multiply and ALUs working on the stored widths are
[I] (this model's reading of the API, not a published datapath).

Results stay in ``[0, F]`` by construction (clamps), so nothing overflows and no
saturation counter is needed.  Against the real-valued operation on ``x = a / F`` the
result differs by at most half a stored LSB for ``mul``, ``mul_b_alpha`` (one rounding),
``k / 2`` LSB for ``mul2..8`` and 0 for the others (exact on the stored values).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.numerics import FixedFormat, uq
from hwsim.spec.scene_features import FINAL_ONLY, LEAF_OPCODES, OPCODES

__all__ = [
    "OPCODES",
    "LEAF_OPCODES",
    "FINAL_ONLY",
    "LATENCY",
    "II",
    "formats",
    "alu",
    "combine_tree",
    "product",
    "Rgba",
]

#: Cycles of the combiner: two ALU levels, one register each ([I]: a clamped add or an
#: 8x12 product fits one 125 MHz cycle in 2003-era standard cells).
LATENCY = 2
II = 1

_SHIFTS = {"mul": 0, "mul2": 1, "mul4": 2, "mul8": 3}


def formats(color_bits: int = 8, alpha_bits: int = 12) -> tuple[FixedFormat, FixedFormat]:
    """The stored-value formats the ALUs work on: ``combine.rgb`` and ``combine.alpha``
    (unorm, raw integers ``0 .. 2**n - 1``)."""
    return (
        uq("combine.rgb", color_bits, 0),
        uq("combine.alpha", alpha_bits, 0),
    )


def product(a: np.ndarray, b: np.ndarray, full: int) -> np.ndarray:
    """``round(a b / full)`` rounding half up, exact (the unorm product)."""
    p = np.asarray(a, dtype=np.int64) * np.asarray(b, dtype=np.int64)
    return (2 * p + full) // (2 * full)


def alu(op: str, a: np.ndarray, b: np.ndarray, bits: int) -> np.ndarray:
    """One ALU channel: leaf opcode ``op`` on unorm ``bits`` operands ``a``, ``b`` (int
    arrays of one shape).  ``mul_b_alpha`` mixes channels and lives in
    :func:`combine_tree`."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    full = (1 << bits) - 1
    if op == "a":
        return a
    if op == "b":
        return b
    if op == "and":
        return a & b
    if op == "or":
        return a | b
    if op == "xor":
        return a ^ b
    if op == "add":
        return np.minimum(a + b, full)
    if op == "sub":
        return np.maximum(a - b, 0)
    if op == "rsub":
        return np.maximum(b - a, 0)
    if op == "min":
        return np.minimum(a, b)
    if op == "max":
        return np.maximum(a, b)
    if op in _SHIFTS:
        return np.minimum(product(a, b, full) << _SHIFTS[op], full)
    raise ValueError(f"unknown combiner opcode {op!r} (allowed: {', '.join(OPCODES)})")


@dataclass(frozen=True)
class Rgba:
    """Stored LUT outputs of a set of samples: ``rgb (n, 3)``, ``alpha (n,)``, int64."""

    rgb: np.ndarray
    alpha: np.ndarray


def _apply(ops: tuple[str, str], x: Rgba, y: Rgba, color_bits: int, alpha_bits: int) -> Rgba:
    rgb_op, alpha_op = ops
    full_alpha = (1 << alpha_bits) - 1
    if rgb_op == "mul_b_alpha":
        rgb = product(x.rgb, y.alpha[:, None], full_alpha)
    else:
        rgb = alu(rgb_op, x.rgb, y.rgb, color_bits)
    if alpha_op == "mul_b_alpha":
        alpha = product(x.alpha, y.alpha, full_alpha)
    else:
        alpha = alu(alpha_op, x.alpha, y.alpha, alpha_bits)
    return Rgba(rgb, alpha)


def combine_tree(
    outs: list[Rgba],
    leaf0: tuple[str, str],
    leaf1: tuple[str, str],
    final: tuple[str, str],
    color_bits: int = 8,
    alpha_bits: int = 12,
) -> Rgba:
    """Merge 1..4 LUT outputs through ``leaf0(lut0, lut1)``, ``leaf1(lut2, lut3)`` and
    ``final(leaf0, leaf1)``; each ALU is a ``(rgb opcode, alpha opcode)`` pair.  A missing
    input is zero; one LUT bypasses the ALUs."""
    if len(outs) == 1:
        return outs[0]
    zero = Rgba(np.zeros_like(outs[0].rgb), np.zeros_like(outs[0].alpha))
    pad = list(outs) + [zero] * (4 - len(outs))
    left = _apply(leaf0, pad[0], pad[1], color_bits, alpha_bits)
    right = _apply(leaf1, pad[2], pad[3], color_bits, alpha_bits)
    return _apply(final, left, right, color_bits, alpha_bits)
