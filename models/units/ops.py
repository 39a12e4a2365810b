"""What each datapath unit does per sample, as arithmetic at its widths: the one inventory
the energy and area model prices (hwsim/energy).

# Ref: models/units/*.py (the bit-exact functions the functional and cycle rungs run; each
#      entry below names the function it is read from); docs/energy.md.

An inventory lists the unit's operators, each with its operand widths, how many the unit
performs per sample and how many the hardware holds.  The hardware is fully pipelined
(one sample per clock), so the operators performed per sample are also what one pipeline
instantiates: priced per action for energy, per instance for area.  The exceptions are
the compositing modes a machine has besides the frame's (:class:`Features`): their
operators are instantiated but perform no action.  Every entry is read from the unit's
bit-exact model, at the widths of the values it computes there (the unit configs,
``models.units.*Config``, and the formats the models state); nothing here is read from
the RTL (rtl/), which "area two ways" compares against (docs/energy.md).

**Pipeline registers.**  A unit has ``LATENCY`` register ranks (its module's constant, the
cycle rung's stage depth).  Each rank holds the values the model's computation has live
at that point, the model's steps taken in order (each unit's function says where its
ranks fall), plus a valid bit (the occupancy the cycle rung's ``Stage`` tracks).  A rank
that ends in a table read is the table's synchronous read port, priced with the table,
so only the values travelling beside it take flip-flops; ranks after the last step carry
the outputs.

**Approximations** (stated, not fitted):

* a subtraction, negation or comparison costs an addition of its width; a comparison with
  zero is a sign test and costs nothing; a nearest-up rounding shift by ``k``
  (``round_shift_raw``) adds half an output step at bit ``k - 1``, below which nothing
  carries: an addition of the value's width less ``k - 1`` (:func:`_round`);
* a square root of a ``2 w``-bit value costs ``w`` additions of ``2 w`` bits (restoring,
  one result bit per step), a division with ``q`` quotient bits ``q`` additions of the
  divisor's width (one trial subtraction a step, its borrow the comparison);
* a product with a constant costs one addition per nonzero bit of the constant beyond the
  first (shift and add; a power of two is wiring);
* selections (multiplexers, ``max``/``min`` outputs, one-hot products), shifts and the
  normaliser's leading-one detector are not priced: the technology has adder, multiplier,
  flip-flop and SRAM figures only (docs/energy.md names what that leaves out);
* a table read costs an SRAM access of the table's size.

Not listed (no unit of :data:`hwsim.energy.model.DATAPATH` computes it per sample):
``composite.to_output`` (per pixel, as the frame is read out), pre-classification
(classify_voxels at voxels and four interpolated channels: VolumePro 1000's
classify-then-interpolate), the 3-D cursor (models/units/cursor.py) and embedded
geometry's depth test (models/units/depth.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cache

import numpy as np

from models.units import classify, composite, crop, gradient, interp, shade

__all__ = ["BLENDS", "SHARED", "Features", "Op", "UNIT_LATENCY", "unit_ops"]


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
#: What the compositor does with a sample: the frame's mode, and for ``composite`` its
#: blend order (models.units.composite).
BLENDS = ("front-to-back", "back-to-front", "mip", "minip", "xray", "iso")


@dataclass(frozen=True)
class Features:
    """Hardware a machine holds beyond the datapath every machine shares (front-to-back
    compositing), from its architecture file, and what one frame uses of it.

    ``blends``: the compositing modes and blend orders besides front-to-back (of
    :data:`BLENDS`); ``early_termination``: the termination compare;
    ``gradient_illumination``: the illumination table and the shader's two products;
    ``cut_planes``: the crop unit's planes.  ``blend`` is the frame's (its operators act,
    the other blends' do not), ``planes_used`` the frame's planes (None: all)."""

    blends: frozenset[str] = frozenset()
    early_termination: bool = False
    gradient_illumination: bool = False
    cut_planes: int = 0
    blend: str = "front-to-back"
    planes_used: int | None = None

    def __post_init__(self) -> None:
        if self.blend not in BLENDS or not self.blends <= set(BLENDS):
            raise ValueError(f"blends are {', '.join(BLENDS)}")


#: The datapath every machine has: front-to-back compositing and nothing more.
SHARED = Features()


def _gated(ops: list[Op], active: bool) -> list[Op]:
    """``ops`` instantiated whether or not they act: no actions when not ``active``."""
    return [replace(op, count=op.count if active else 0.0, copies=op.instances) for op in ops]


def _const_adds(k: int) -> int:
    """Additions of a product with the constant ``k`` (shift and add)."""
    return max(bin(int(k)).count("1") - 1, 0)


def _ranks(unit: str, live: list[int]) -> list[Op]:
    """The unit's ``LATENCY`` ranks: ``live[i]`` bits after the model's step ``i`` (the
    last repeated over the ranks left), each with its valid bit."""
    latency = UNIT_LATENCY[unit]
    if len(live) > latency:
        raise ValueError(f"{unit}: {len(live)} steps in {latency} ranks")
    bits = live + [live[-1]] * (latency - len(live))
    return [Op("register", b + 1) for b in bits]


@cache
def _expansion(bits: int) -> tuple[int, int]:
    """``classify.expand`` of a ``bits``-bit unorm as hardware: ``x 4096 / (2**n - 1) = x
    2**(12 - n) (1 + 2**-n + 2**-2n + ...)``, the fewest shifted copies of ``x`` (each cut
    to the fewest fraction bits) whose rounded sum equals ``expand`` for every stored
    value.  Returns (copies, width of their sum); 0 copies: 4096 / (2**n - 1) is a power of
    two (one bit), a shift."""
    full = (1 << bits) - 1
    if 4096 % full == 0:
        return 0, bits + 12
    x = np.arange(1 << bits, dtype=np.int64)
    ref = classify.expand(x, bits)
    for terms in range(1, 14):
        for frac in range(1, 24):
            total = sum(((x << 12) << frac) >> (bits * (k + 1)) for k in range(terms))
            if np.array_equal((total + (1 << (frac - 1))) >> frac, ref):
                return terms, 13 + frac  # the sum is at most 4096: 13 integer bits
    raise ValueError(f"classify.expand of {bits} bits: no shift-and-add form found")


def _round(width: int, shift: int, count: float = 1) -> Op:
    """``count`` nearest-up roundings of a ``width``-bit value by ``shift`` bits: the half
    is added from bit ``shift - 1`` up (``round_shift_raw``; a shift of 0 or less adds
    nothing: a count of 0)."""
    return Op("add", width - shift + 1, count=count if shift > 0 else 0)


def _lerps(n: int, sample_bits: int, weight_bits: int) -> list[Op]:
    """``n`` lerps ``a + round((b - a) w)`` (``interp.lerp_raw``): the difference, the
    product, the rounding add and the sum."""
    w = weight_bits + 1  # UQ1.W weights (interp.InterpConfig.weight)
    return [
        Op("add", sample_bits + 1, count=n),  # b - a
        Op("mult", sample_bits + 1, w, count=n),  # (b - a) f
        _round(sample_bits + 1 + w, weight_bits, n),  # round_shift_raw(..., W)
        Op("add", sample_bits + 1, count=n),  # a + ...
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
    gm_entries: int = 64,
    xray_frac_bits: int = 12,
    xray_acc_bits: int = 48,
    features: Features = SHARED,
) -> list[Op]:
    """The operators ``unit`` performs per sample and holds (``lerps``: 7 for a trilinear
    sample, 3 for Cube-4's bilinear one on a voxel slice; ``lights``: the lights shaded
    per sample, the hardware's when pricing area)."""
    s = voxel_bits + sample_frac_bits  # an interpolated sample (interp.interpolate)
    # A central difference of two samples (gradient.sample_differences), or an
    # interpolated voxel difference (gradient.voxel_difference: B + 2 bits, signed).
    g = s + 1 if gradient_source == "sample" else s + 2
    f = normal_frac_bits
    if unit == "interp":
        ops = _interp(s, voxel_bits, weight_bits, lerps)
    elif unit == "gradient":
        ops = _gradient(s, g, voxel_bits, weight_bits, lerps, gradient_source, f)
    elif unit == "classify":
        ops = _classify(s, g, lut_entries, color_bits, alpha_bits, gm_entries, features)
    elif unit == "shade" and shading == "reflectance-map":
        ops = _shade_maps(f, map_size, features)
    elif unit == "shade":
        ops = _shade_phong(f, lights, spec_table_entries, features)
    elif unit == "composite":
        ops = _composite(s, acc_frac_bits + 1, xray_frac_bits, xray_acc_bits, features)
    elif unit == "crop":
        ops = _crop(features)
    else:
        raise KeyError(unit)
    return [op for op in ops if op.instances > 0]  # e.g. a product with a power of two


# Colours and opacities between units: UQ1.12, 4096 exactly 1.0, so 13 bits
# (classify.ONE, shade.ONE, composite.ALPHA).
_C = 13
# Shading coefficients and light intensities: UQ4.8 (shade._COEF fraction bits).
_COEF = 12
# The gradient unit's square-root and divider ranks (rtl/gradient.py SQRT_STAGES and
# DIVIDE_STAGES: the RTL may import models, not the reverse; its LATENCY checks the sum).
_SQRT_RANKS, _DIVIDE_RANKS = 12, 6


def _interp(s: int, voxel_bits: int, weight_bits: int, lerps: int) -> list[Op]:
    """interp.lerp_corners: the lerps of ``lerps + 1`` corners, x, then y, then z.  Ranks
    (the RTL's stage plan, rtl/interp.py): the promoted corners and weights
    (interp.promote_raw: ``B`` bits each, the ``S`` promoted bits being zeros), then per
    level of lerps its products ``(b - a) w`` beside their ``a`` ends, and what the level
    leaves (2**k samples), each with the weights still to use; Cube-4's bilinear sample
    has two levels and carries its result."""
    w = weight_bits + 1
    levels = (lerps + 1).bit_length() - 1
    live = [(lerps + 1) * voxel_bits + levels * w]
    for k in range(1, levels + 1):
        n, later = (lerps + 1) >> k, (levels - k) * w
        live += [n * (s + 1 + w) + n * s + later, n * s + later]
    return _lerps(lerps, s, weight_bits) + _ranks("interp", live)


def _gradient(
    s: int, g: int, voxel_bits: int, weight_bits: int, lerps: int, source: str, f: int
) -> list[Op]:
    """gradient.sample_differences (or voxel differences, interpolated), to_world,
    magnitude and normal_raw.  Ranks: the world-scaled differences; after normal_raw's
    normaliser (its shifted components, their root and the magnitude); the normals and
    the magnitude."""
    n = f + 2  # a normal component, SQ1.F (gradient.normals)
    # normal_raw shifts small vectors until their root has F + 2 bits: the shifted
    # components and root fit max(g, F + 3) bits (|N| < 2**(F + 2) after a shift).
    g2 = max(g, f + 3)
    if source == "sample":
        diffs = [Op("add", g, count=3)]  # sample_differences: s[0::2] - s[1::2]
    else:
        diffs = [
            Op("add", voxel_bits + 1, count=3),  # voxel_difference: v[i + 1] - v[i - 1]
            *_lerps(3 * lerps, g, weight_bits),  # the three interpolated with the taps
        ]
    ops = diffs + [
        # to_world: g * ratio (UQ1.12, _RATIO_BITS), round_shift by 12
        Op("mult", g, gradient._RATIO_BITS + 1, count=3),
        _round(g + gradient._RATIO_BITS + 1, gradient._RATIO_BITS, 3),
        # magnitude / normal_raw: m0 = isqrt_raw(gx*gx + gy*gy + gz*gz)
        Op("mult", g, g, count=3),
        Op("add", 2 * g, count=2),
        Op("add", 2 * g, count=g),  # the root, a result bit per step
        # normal_raw: shift = max(F + 2 - bit_length_raw(m0), 0) (the min(..., 40) never
        # binds: F <= 20); the leading-one detector and the three shifts are not priced
        Op("add", (f + 2).bit_length() + 1),
        # normal_raw: safe = isqrt_raw of the shifted components' squares
        Op("mult", g2, g2, count=3),
        Op("add", 2 * g2, count=2),
        Op("add", 2 * g2, count=g2),
        # normal_raw, per component: -g << f; 2 (...) + safe; floor_div_raw by 2 safe
        # (F + 2 quotient bits, |N| <= 2**F + 1); clip to +-2**F (two compares)
        Op("add", g2, count=3),
        Op("add", g2 + f + 2, count=3),
        Op("add", g2 + 1, count=3 * n),
        Op("add", n, count=6),
    ]
    # Ranks: the RTL's stage plan (rtl/gradient.py): differences; world-scaled; squares
    # beside the components; |g|^2; the normalised square and shifted components; the
    # square root's remainder, partial root and unconsumed input bits (12 ranks); the
    # dividers' numerators, signs and divisor; their remainders, quotient bits and
    # unconsumed numerator bits (6 ranks); the normals and the magnitude.
    s2, shift, side = 2 * g + 1, (f + 2).bit_length(), 3 * g2 + (f + 2).bit_length() + 1
    num = g2 + 2 * f + 5
    ranks = [
        3 * g,
        3 * g,
        3 * 2 * g + 3 * g,
        s2 + 3 * g,
        max(s2, 2 * (f + 2)) + side,
        *[max(s2, 2 * (f + 2)) + 2 + side] * _SQRT_RANKS,
        3 * (num + 1) + 2 * (g + 1) + shift + 1,
        *[3 * (g + 2 + n) + (g + 1) + 3 + (g + 1) + 1] * _DIVIDE_RANKS,
        3 * n + g,
    ]
    return ops + _ranks("gradient", ranks)


def _classify(
    s: int,
    g: int,
    entries: int,
    color_bits: int,
    alpha_bits: int,
    gm_entries: int,
    features: Features,
) -> list[Op]:
    """classify.lut_index_raw, the LUT read, expand (read-out), gm_index_raw, the
    magnitude table and scale_alpha_raw (modulate); with gradient illumination, the
    second magnitude table (build_gm_table(illumination=True), indexed alike).  Ranks: the
    two tables' synchronous reads; the UQ1.12 colours, opacity (and illumination factor)."""
    ops: list[Op] = []
    shift = s - (entries.bit_length() - 1)
    if shift > 0:  # lut_index_raw: round_shift_raw(sample, shift), min(..., entries - 1)
        ops += [_round(s, shift), Op("add", entries.bit_length())]
    ops.append(Op("table", 3 * color_bits + alpha_bits, entries))  # the LUT, unorm
    for bits, count in ((color_bits, 3), (alpha_bits, 1)):  # expand: a constant multiply
        copies, width = _expansion(bits)
        if copies:
            ops.append(Op("add", width, count=count * (copies - 1)))  # the copies' sum
            ops.append(_round(width, width - 13, count))  # ... rounded to UQ1.12
    # gm_index_raw: magnitude (g bits: |g| < sqrt(3) 2**(g - 1)) times the UQ0.24 scale
    # (gm_scale), round_shift by 24, min(..., gm_entries - 1)
    scale = classify._GM_SCALE_BITS
    ops += [
        Op("mult", g, scale),
        _round(g + scale, scale),
        Op("add", g + 1),
        Op("table", _C, gm_entries),  # build_gm_table: UQ1.12 factors
        Op("mult", _C, _C),  # scale_alpha_raw: alpha * factor
        _round(2 * _C, 12),  # ... round_shift by 12
    ]
    out = 4 * _C
    if features.gradient_illumination:
        ops.append(Op("table", _C, gm_entries))  # the illumination factors, same index
        out += _C
    # Ranks (the RTL's stage plan, rtl/classify.py): the LUT index and the magnitude
    # product; the two tables' synchronous reads; the expanded colours and opacity beside
    # the magnitude factor; the modulated outputs.
    ranks = [entries.bit_length() + g + scale, 0, 4 * _C + _C, out]
    return ops + _ranks("classify", ranks)


def _combine_ranks(d: int) -> list[int]:
    """The combine's two ranks (rtl/shade.py): the ambient and diffuse products of each
    channel beside the specular term; the shaded colours."""
    ka = (((1 << _COEF) - 1) * 4096 >> 8).bit_length()
    return [3 * (ka + d + 1) + d, 3 * _C]


def _shade_combine(d: int) -> list[Op]:
    """shade.shade_raw per colour channel: ka c and diffuse c, each rounded, plus the
    specular term (``d`` bits: the diffuse and specular sums), clamped at 1.0."""
    ka = (((1 << _COEF) - 1) * 4096 >> 8).bit_length()  # round(ka c / 2**8): 16 bits
    return [
        Op("mult", _COEF, _C, count=3),  # ka * rgb
        _round(_COEF + _C, 8, 3),  # ... round_shift by shade._COEF
        Op("mult", d, _C, count=3),  # diffuse * rgb
        _round(d + _C, 12, 3),  # ... round_shift by 12
        Op("add", max(ka, d) + 1, count=3),  # the two terms' sum
        Op("add", max(ka, d) + 2, count=3),  # ... plus specular
        Op("add", max(ka, d) + 2, count=3),  # min(..., ONE); max(..., 0) a sign test
    ]


#: A diffuse or specular term of one light (shade.light_terms_raw, specular_raw):
#: round(I k x / 2**16) of UQ4.8 I and k and UQ1.12 x <= 1.0, UQ8.12.
_TERM = 20


def _illumination(features: Features) -> list[Op]:
    """shade.shade with ``illumination``: diffuse and specular times the UQ1.12 factor,
    each rounded (machines with gradient illumination)."""
    if not features.gradient_illumination:
        return []
    return [Op("mult", _TERM, _C, count=2), _round(_TERM + _C, 12, 2)]


def _shade_maps(f: int, r: int, features: Features) -> list[Op]:
    """shade.cell_index_raw, the two map reads, shade_raw.  Ranks: cell_index_raw's face
    (the major component, the face's axis and sign, the other two components) with the
    colours; the cell index and colours; the maps' synchronous reads and colours; the
    shaded colours."""
    n = f + 2
    q = r.bit_length()  # a cell coordinate: floor(...) <= r, clamped to r - 1
    cell = 6 * r * r  # the zero normal's entry (the last)
    ops = [
        Op("add", n, count=3),  # np.abs(nx), np.abs(ny), np.abs(nz)
        Op("add", f + 1, count=3),  # ax >= ay, ax >= az, ay >= az
        Op("add", n, count=2),  # u + safe, w + safe (safe = max(major, 1): a zero test)
        Op("add", n + q, count=2 * _const_adds(r)),  # (...) * r
        Op("add", f + 2, count=2 * q),  # // (2 safe): q quotient bits
        Op("add", q, count=2),  # min(..., r - 1); max(..., 0) a sign test
    ]
    if r & (r - 1):  # (((axis, sign) r + iu) r + iw): wiring when r is a power of two
        ops.append(Op("add", cell.bit_length(), count=2 * _const_adds(r) + 2))
    # Map entries: one light's diffuse or specular term, UQ8.12 (setup: maps from
    # _lighting_terms; more lights' sums are not widened here).
    ops.append(Op("table", _TERM, cell + 1, count=2, copies=2))
    ops += _illumination(features) + _shade_combine(_TERM)
    illum = _C if features.gradient_illumination else 0  # the factor, carried to its use
    rgb = 3 * _C + illum
    face = (f + 1) + 2 + 1 + 2 * n  # major, axis (sy + 2 sz), sign, u, w
    # Ranks (the RTL's stage plan, rtl/shade.py): the face; the cell numerators and the
    # divisor; the dividers' remainders, quotient and unconsumed bits (4 ranks, half the
    # numerator's bits unconsumed on average); the cell
    # index; the maps' synchronous reads; the combine's products; the shaded colours.
    divide = 2 * (n + 2 + q + (n + 1 + q) // 2) + (n + 1) + 4 + rgb  # bits consumed on the way
    ranks = [
        face + rgb,
        2 * (n + 1 + q) + (n + 1) + 4 + rgb,
        *[divide] * 4,
        cell.bit_length() + rgb,
        rgb,
        *_combine_ranks(_TERM),
    ]
    return ops + _ranks("shade", ranks)


def _shade_phong(f: int, lights: int, entries: int, features: Features) -> list[Op]:
    """shade.light_terms_raw and specular_raw per light, the light sums, shade_raw.
    Ranks: each light's diffuse term and table index; the table's synchronous read beside
    the diffuse terms; the diffuse and specular sums; the shaded colours."""
    n = f + 2
    dot = 2 * n + 2  # three SQ1.F x SQ1.F products summed
    shift = 2 * f - 12  # round_shift_raw(..., 2 f - 12) to UQ1.12
    nd = dot - max(shift, 0)
    index = entries.bit_length()  # round(ndh entries / 4096) <= entries
    d = _TERM + (lights - 1).bit_length()  # the sums over the lights
    per_light = [
        Op("mult", n, n, count=6),  # N.L and N.H
        Op("add", dot, count=4),  # ... their sums
        _round(dot, shift, 2),  # ... round_shift_raw
        Op("add", nd, count=2),  # min(ndh, ONE), min(ndl, ONE); max(..., 0) sign tests
        Op("mult", _COEF, _COEF, count=2),  # intensity * kd, intensity * ks
        Op("mult", 2 * _COEF, _C, count=2),  # ... * min(ndl, ONE), ... * spec[si]
        _round(2 * _COEF + _C, 16, 2),  # ... round_shift_raw by 16
        Op("add", _C + index, count=_const_adds(entries)),  # ndh * entries
        _round(_C + index, 12),  # ... round_shift_raw by 12
        Op("table", _C, entries + 1),  # the specular table x**n (setup), UQ1.12
    ]
    ops = [replace(op, count=op.count * lights) for op in per_light]
    ops.append(Op("add", d, count=2 * (lights - 1)))  # diffuse += d, specular += s
    ops += _illumination(features) + _shade_combine(d)
    illum = _C if features.gradient_illumination else 0
    rgb = 3 * _C + illum
    # Ranks (the RTL's stage plan, rtl/shade.py): per light the six products, the two
    # dot products, the clamped N.L and table index, the table read beside N.L and the two
    # coefficient products, the two terms; the light sums (carried to the combine); the
    # combine's products; the shaded colours.
    ranks = [
        lights * 6 * 2 * n + rgb,
        lights * 2 * dot + rgb,
        lights * (_C + index) + rgb,
        lights * (_C + 2 * 2 * _COEF) + rgb,
        lights * 2 * _TERM + rgb,
        *[2 * d + rgb] * 3,
        *_combine_ranks(d),
    ]
    return ops + _ranks("shade", ranks)


def _composite(s: int, acc: int, xray_frac: int, xray_acc: int, features: Features) -> list[Op]:
    """composite.correct_opacity, front_to_back (ftb_weight_raw, ftb_colour_raw, the
    accumulator's saturation), terminated, and the machine's other blends (mip, minip,
    iso_hit, xray, back_to_front's btf_raw).  Ranks (LATENCY: table 1, multiply 1,
    products 1, accumulate 1; listed below); MIP, MinIP keep the ray's value in the same
    accumulator."""
    blend = features.blend
    ftb = [
        Op("add", _C, count=4),  # _saturate_unit(alpha), _check_unit_inputs(rgb): > 4096
        Op("table", _C, (1 << composite._ALPHA_BITS) + 1),  # correction_table, UQ1.12
        Op("add", acc),  # ftb_weight_raw: one - A
        Op("mult", acc, _C),  # ... (one - A) a
        _round(acc + _C, 12),  # ... round_shift_raw by 12
        Op("mult", acc, _C, count=3),  # ftb_colour_raw: w c
        _round(acc + _C, 12, 3),  # ... round_shift_raw by 12
        Op("add", acc, count=4),  # C += ..., A += w
        Op("add", acc + 1, count=4),  # _saturate_unit(cur, acc): > one
    ]
    ops = _gated(ftb, blend in ("front-to-back", "back-to-front"))
    if features.early_termination:
        ops += _gated([Op("add", acc)], blend == "front-to-back")  # terminated: A >= thr
    for mode in ("mip", "minip", "iso"):  # max, min, sample >= threshold
        if mode in features.blends:
            ops += _gated([Op("add", s)], blend == mode)
    if "back-to-front" in features.blends:
        ops += _gated(
            [
                Op("add", _C),  # btf_raw: 4096 - alpha
                Op("mult", _C, _C, count=3),  # alpha * src (the opacity's src is 4096)
                Op("mult", _C, acc, count=4),  # (4096 - alpha) * acc
                Op("add", acc + _C, count=4),  # the two products' sum
                _round(acc + _C + 1, 12, 4),  # ... round_shift_raw by 12
            ],
            blend == "back-to-front",
        )
    if "xray" in features.blends:
        ops += _gated(
            [
                Op("mult", s, 8 + xray_frac),  # xray: sample * w (xray_dt UQ8.F)
                Op("add", xray_acc, count=2),  # acc + s w; dt_sum + w (the count)
                Op("add", xray_acc, count=2),  # xray_acc.saturate
            ],
            blend == "xray",
        )
    # The accumulators a sample carries: RGBA UQ1.F, or X-ray's sum and step count; the
    # back-to-front products in place of w, the accumulators and the colours.
    regs = max(4 * acc, 2 * xray_acc if "xray" in features.blends else 0)
    mult_rank = acc + regs + 3 * _C
    if "back-to-front" in features.blends:
        mult_rank = max(mult_rank, 4 * (acc + _C + 1))
    last = regs + (1 if features.early_termination else 0)  # the termination flag
    # Ranks (the RTL's stage plan, rtl/composite.py): the ROM read beside the accumulators,
    # 1 - A and the colours; the weight beside them; the colour products w c beside w and
    # the accumulators; the updated accumulators.
    products = max(3 * acc + acc + regs, mult_rank)
    ranks = [regs + acc + 3 * _C, mult_rank, products, last]
    return ops + _ranks("composite", ranks)


def _crop(features: Features) -> list[Op]:
    """crop.crop_keep (three slabs: a comparator pair each, the count of slabs hit against
    the mode's threshold) and cut_factor per plane, then the product of the factor and the
    opacity (the back end's classify.scale_alpha_raw).  Ranks (LATENCY: dot product 1,
    ramp 1): the keep bit and each plane's distance; the keep bit and the factor."""
    cfg = crop.DEFAULT
    pos = cfg.pos.width  # cut.pos SQ12.F
    nrm = cfg.normal.width  # cut.normal SQ1.F
    dist = cfg.dist.width  # cut.dist SQ12.F
    dot = pos + nrm + 2  # three products summed (exact)
    rounded = dot - (cfg.pos_frac_bits + cfg.normal_frac_bits - cfg.dist_frac_bits)
    ramp_shift = cfg.dist_frac_bits + cfg.inv_frac_bits - 12
    ramp = 21 + cfg.inv.width  # clip(beyond, 0, 2**20) * inv
    ops = [
        # crop_keep: lo <= c and c <= hi per axis, on sample positions of 16 bits (the
        # model compares them in float64 or with any frac_bits: the width is [I])
        Op("add", 16, count=6),
        Op("add", 2, count=3),  # the slabs hit (a 2-bit count) and >= slabs_needed
    ]
    planes = features.cut_planes
    used = planes if features.planes_used is None else min(features.planes_used, planes)
    per_plane = [
        Op("mult", pos, nrm, count=3),  # p @ n_raw
        Op("add", dot, count=2),  # ... summed
        _round(dot, dot - rounded),  # round_shift by pos + normal - dist fraction bits
        Op("add", rounded + 1),  # - off
        Op("add", rounded + 1, count=2),  # dist.saturate: two bounds
        Op("add", dist, count=2),  # np.abs(d), - half
        Op("add", dist),  # clip(beyond, 0, 2**20)
        Op("mult", 21, cfg.inv.width),  # beyond * inv (UQ16.F)
        _round(ramp, ramp_shift),  # ... round_shift by dist + inv - 12 fraction bits
        Op("add", ramp - ramp_shift),  # ONE - ramp (clip(..., 0, ONE): a sign test)
        Op("add", _C),  # invert: ONE - f
        Op("mult", _C, _C),  # factor * f
        _round(2 * _C, 12),  # ... round_shift by 12
    ]
    for op in per_plane:
        ops.append(replace(op, count=op.count * used, copies=op.count * planes))
    if planes:  # alpha * factor, rounded (classify.scale_alpha_raw in models/backend.py)
        ops += _gated([Op("mult", _C, _C), _round(2 * _C, 12)], used > 0)
    return ops + _ranks("crop", [1 + planes * dist, 1 + (_C if planes else 0)])
