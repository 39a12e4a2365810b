"""What each datapath unit does per sample, as arithmetic at its widths: the one inventory
the energy and area model prices (hwsim/energy).

# Ref: models/units/*.py (the arithmetic these lists count: lerps, differences, the
#      normal's root and divisions, Phong's dot products, the blend); docs/energy.md.

An inventory lists the unit's operators, each with its operand widths and how many the
unit performs per sample.  The hardware is fully pipelined (one sample per clock), so the
same list is also what one pipeline instantiates: priced per action for energy, per
instance for area.  Pipeline registers are one word per stage (``LATENCY`` stages of the
unit's output width); tables are read once per sample.  Widths follow the unit configs
(``models.units.*Config``); nothing here is a timing rule.

Approximations (stated, not fitted): a subtraction or comparison costs an addition of its
width; a square root of a ``2 w``-bit value costs ``w`` additions of ``2 w`` bits
(restoring, one result bit per step), a division with ``q`` quotient bits ``q``
additions of the divisor's width (the RTL's shift-subtract dividers); a table read costs
an SRAM access of the table's size.
"""

from __future__ import annotations

from dataclasses import dataclass

from models.units import classify, composite, crop, gradient, interp, shade

__all__ = ["Op", "UNIT_LATENCY", "unit_ops"]


@dataclass(frozen=True)
class Op:
    """``count`` operations per sample: ``kind`` ``add`` (``a`` bits), ``mult`` (``a`` x ``b``
    bits), ``table`` (a read of an ``a``-bit word of ``b`` entries) or ``register`` (``a``
    bits written once).  ``copies``: how many the hardware holds (default: one per
    operation for operators and registers, a single table however often it is read)."""

    kind: str
    a: int
    b: int = 0
    count: float = 1.0
    copies: float | None = None

    @property
    def instances(self) -> float:
        if self.copies is not None:
            return self.copies
        return 1.0 if self.kind == "table" else self.count


#: Pipeline depth of each unit (its module's ``LATENCY``), for its registers.
UNIT_LATENCY = {
    m.__name__.rsplit(".", 1)[1]: m.LATENCY
    for m in (interp, gradient, classify, shade, composite, crop)
}


def _lerps(n: int, sample_bits: int, weight_bits: int) -> list[Op]:
    """``n`` lerps ``a + round((b - a) w)``: the difference, the product, the rounding add
    and the sum."""
    w = weight_bits + 1  # UQ1.W weights
    return [
        Op("add", sample_bits + 1, count=n),
        Op("mult", sample_bits + 1, w, count=n),
        Op("add", sample_bits + w, count=n),
        Op("add", sample_bits + 1, count=n),
    ]


def unit_ops(
    unit: str,
    *,
    voxel_bits: int,
    sample_frac_bits: int,
    weight_bits: int,
    lerps: int,
    gradient_source: str,
    normal_frac_bits: int,
    lut_entries: int,
    color_bits: int,
    alpha_bits: int,
    lights: int,
    shading: str,
    spec_table_entries: int,
    map_size: int,
    acc_frac_bits: int,
) -> list[Op]:
    """The operators ``unit`` performs per sample (``lerps``: 7 for a trilinear sample, 3
    for Cube-4's bilinear one on a voxel slice)."""
    s = voxel_bits + sample_frac_bits  # an interpolated sample
    g = s + 2  # a central difference of samples, and its sign
    n = normal_frac_bits + 2  # a normal component (S1.N)
    c = 12  # colours and opacities between units (UQ0.12, models.units.classify)
    acc = acc_frac_bits + 1
    registers = [Op("register", {"interp": s, "gradient": 3 * g, "classify": 4 * c,
                                 "shade": 3 * c, "composite": 4 * acc, "crop": 8}[unit],
                    count=UNIT_LATENCY[unit])]  # fmt: skip
    if unit == "interp":
        return _lerps(lerps, s, weight_bits) + registers
    if unit == "gradient":
        if gradient_source == "voxel":  # interpolated voxel differences: 3 more samples
            diffs = _lerps(3 * lerps, g, weight_bits)
        else:  # central differences of the neighbouring samples the ring delivers
            diffs = [Op("add", g, count=3)]
        norm = [
            Op("mult", g, g, count=3),  # squares
            Op("add", 2 * g, count=2),  # their sum
            Op("add", 2 * g, count=g),  # the square root, a bit per step
            Op("add", g + n, count=3 * n),  # three divisions, n quotient bits each
        ]
        return diffs + norm + registers
    if unit == "classify":
        return [Op("table", 3 * color_bits + alpha_bits, lut_entries)] + registers
    if unit == "shade":
        if shading == "reflectance-map":  # diffuse and specular maps, one read each
            # Map entries sum any number of lights: UQ8.12 (rtl/shade.py MAP_BITS).
            light = [Op("table", 20, 6 * map_size * map_size + 1, count=2, copies=2)]
        else:  # N.L and N.H, the specular table, the light's intensity
            light = [
                Op("mult", n, c, count=6 * lights),
                Op("add", n + c, count=4 * lights),
                Op("table", c, spec_table_entries, count=lights),
                Op("mult", c, c, count=2 * lights),
            ]
        colour = [Op("mult", c, c, count=6), Op("add", 2 * c, count=6)]  # ka + kd d + ks s
        return light + colour + registers
    if unit == "composite":
        return [
            Op("table", c, 4097),  # the opacity-correction ROM
            Op("mult", c, acc, count=4),  # the weight and three colours
            Op("add", acc, count=4),
        ] + registers
    if unit == "crop":
        return [Op("add", 16, count=6)] + registers  # the box's six comparisons
    raise KeyError(unit)
