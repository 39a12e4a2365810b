"""Compositor: opacity correction, front-to-back / back-to-front blending, ERT, MIP, MinIP,
X-ray sum, iso first hit, output conversion -- bit-exact in fixed point.

# Ref: architectures.md sections 3 (VolumePro 500 blend modes FTB/MIP/MinIP, RGBA8 pixels),
#      4 (VolumePro 1000 ERT threshold, sampling factor 0.5..8, RGBA12), 6.5 (opacity
#      correction), 9.1 and 9.3 (compositor; latency [I]); golden: hwsim/golden/render.py.

Formats (all ``nearest-up`` = ``floor(x + 1/2)``; see docs/units/composite-crop-skew.md)::

    composite.alpha   UQ1.12  sample opacity and colour, 4096 = 1.0 exactly
    composite.acc     UQ1.16  accumulated premultiplied RGB and A, saturating at 1.0
    composite.ratio   UQ4.8   opacity-correction exponent k = dt / min(spacing)
    composite.xray_dt UQ8.12  X-ray step weight
    composite.xray    48-bit unsigned, S + 12 fraction bits, saturating
    composite.out     unorm ``output_bits`` (1.0 -> 2**bits - 1)

Front-to-back, per sample (one rounding per product)::

    w  = round((1 - A) * a)            UQ1.16      (exact product has 28 fraction bits)
    C += round(w * c)                  UQ1.16
    A += w

Since ``round`` never exceeds an integer bound of the exact product, ``w <= 1 - A`` and
``round(w c) <= w``: ``C <= A <= 1`` holds by construction and saturation (counted) only
catches out-of-range inputs.  Against float64 compositing of the *same* quantised
alphas and colours: ``|dA| <= n 2**-17`` (and ``<= 2**-17 / a`` for constant ``a``),
``|dC| <= 3 n 2**-17`` for ``n`` samples.  Underflow: ``w`` rounds to 0 once
``(1 - A)_raw * a_raw < 2048``; accumulated opacity stalls at ``1 - A < 2048 / a_raw``
LSBs (for ``a = 1/4096``: ``A`` stops at ``1 - 2047 * 2**-16 = 0.968765``).

Back-to-front: ``C = round((a c 2**4 + (1 - a) C) / 2**12)``, ``A`` likewise: one
rounding of a convex combination, so ``C, A <= 1`` again.

A ray must appear at most once per call of the blending functions (as in the golden
renderer); MIP / MinIP / X-ray accept repeats.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from hwsim.numerics import (
    ROUNDING_CODES,
    SATURATIONS,
    FixedFormat,
    OverflowError_,
    round_shift,
    round_shift_raw,
    uq,
)

__all__ = [
    "ALPHA",
    "ACC",
    "II",
    "LATENCY",
    "CompositeConfig",
    "back_to_front",
    "btf_raw",
    "correct_opacity",
    "correction_table",
    "front_to_back",
    "ftb_weight_raw",
    "ftb_colour_raw",
    "correction_for",
    "iso_hit",
    "minip",
    "mip",
    "output_to_float",
    "terminated",
    "to_output",
    "xray",
    "ftb_error_bound",
]

#: Cycles from sample in to accumulator updated: the RTL's stage plan (rtl/composite.py
#: STAGES: opacity-correction table 1, weight multiply 1, colour products 1, accumulate
#: 1), so every stage meets a 125 MHz clock at 0.35 um by the project's depth estimate
#: (issue 34); within architectures.md 9.3's "compositor 2-4" [I].  Three stages (products
#: and accumulate in one) were ~50 gates deep (~106 MHz).
LATENCY = 4
#: One sample per clock per pipeline (architectures.md 9.4 row 1).
II = 1

_ALPHA_BITS = 12
#: Sample opacity / colour entering the compositor (UQ1.12, 4096 = 1.0).
ALPHA = uq("composite.alpha", 1, _ALPHA_BITS)
#: Accumulator at the default width (UQ1.16); ``CompositeConfig.acc`` gives the configured one.
ACC = uq("composite.acc", 1, 16)


@dataclass(frozen=True, kw_only=True)
class CompositeConfig:
    """Widths of the compositor (defaults: VolumePro 500; widths are [I]).

    Parameters
    ----------
    acc_frac_bits : int
        Fraction bits of the RGB and A accumulators (UQ1.F, saturating at 1.0).
    output_bits : int
        Unorm bits per channel of the pixel leaving the chip (8: VP500 RGBA8 [V];
        12: VP1000 RGBA12 [V]).
    ratio_frac_bits : int
        Fraction bits of the opacity-correction exponent (UQ4.F).
    xray_frac_bits : int
        Fraction bits of the X-ray step weight (UQ8.F).
    xray_acc_bits : int
        Width of the X-ray accumulator (unsigned, saturating).
    sample_frac_bits : int
        Fraction bits ``S`` of interpolated samples (X-ray accumulator format).
    """

    acc_frac_bits: int = 16
    output_bits: int = 8
    ratio_frac_bits: int = 8
    xray_frac_bits: int = 12
    xray_acc_bits: int = 48
    sample_frac_bits: int = 4

    def __post_init__(self) -> None:
        if not _ALPHA_BITS <= self.acc_frac_bits <= 30:
            raise ValueError("acc_frac_bits must be 12..30")
        if not 1 <= self.output_bits <= self.acc_frac_bits:
            raise ValueError("output_bits must be 1..acc_frac_bits")
        if not 1 <= self.ratio_frac_bits <= 16 or not 1 <= self.xray_frac_bits <= 20:
            raise ValueError("ratio_frac_bits 1..16, xray_frac_bits 1..20")
        if not self.xray_frac_bits + self.sample_frac_bits < self.xray_acc_bits <= 62:
            raise ValueError("xray_acc_bits must exceed the fraction bits and be <= 62")

    @property
    def acc(self) -> FixedFormat:
        """``composite.acc`` UQ1.F."""
        return uq("composite.acc", 1, self.acc_frac_bits)

    @property
    def ratio(self) -> FixedFormat:
        """``composite.ratio`` UQ4.F: opacity-correction exponent."""
        return uq("composite.ratio", 4, self.ratio_frac_bits)

    @property
    def xray_dt(self) -> FixedFormat:
        """``composite.xray_dt`` UQ8.F: X-ray step weight."""
        return uq("composite.xray_dt", 8, self.xray_frac_bits)

    @property
    def xray_acc(self) -> FixedFormat:
        """``composite.xray``: unsigned ``xray_acc_bits`` wide, ``S + xray_frac_bits``
        fraction bits."""
        frac = self.sample_frac_bits + self.xray_frac_bits
        return uq("composite.xray", self.xray_acc_bits - frac, frac)

    @property
    def out(self) -> FixedFormat:
        """``composite.out``: the unorm pixel as raw integers (0 .. 2**bits - 1)."""
        return uq("composite.out", self.output_bits, 0)


DEFAULT = CompositeConfig()


def _saturate_unit(raw: np.ndarray, fmt: FixedFormat) -> np.ndarray:
    """Apply ``fmt``'s overflow rule with the ceiling at exactly 1.0 (``2**frac_bits``):
    values outside the format are clipped and counted by :meth:`FixedFormat.saturate`,
    values inside it but above 1.0 here, each counted once under ``fmt.name``."""
    raw = np.asarray(raw, dtype=np.int64)
    one = 1 << fmt.frac_bits
    if raw.size == 0 or (fmt.raw_min <= raw.min() and raw.max() <= one):
        return raw  # the common case: nothing to clip or count, two reductions, no copy
    over = (raw > one) & (raw <= fmt.raw_max)
    count = int(np.count_nonzero(over))
    raw = fmt.saturate(raw)
    if count:
        if fmt.overflow == "error":
            raise OverflowError_(f"{fmt.name}: {count} values above 1.0")
        SATURATIONS[fmt.name] += count
    return np.minimum(raw, one)


@lru_cache(maxsize=4096)
def _table(k_raw: int, ratio_frac_bits: int) -> np.ndarray:
    one = 1 << _ALPHA_BITS
    k = k_raw / (1 << ratio_frac_bits)
    a = np.arange(one + 1, dtype=np.float64) / one
    table = np.floor(one * (1.0 - (1.0 - a) ** k) + 0.5).astype(np.int64)
    table[0], table[one] = 0, one
    table = np.maximum.accumulate(np.clip(table, 0, one))  # float pow cannot break monotony
    table.flags.writeable = False
    return table


def correction_table(k_raw: int, cfg: CompositeConfig = DEFAULT) -> np.ndarray:
    """The opacity-correction ROM for one exponent.

    Parameters
    ----------
    k_raw : int
        Exponent ``k`` as a raw UQ4.F integer (``k = k_raw / 2**ratio_frac_bits``), >= 1.
    cfg : CompositeConfig

    Returns
    -------
    numpy.ndarray
        ``(4097,)`` int64, read-only: entry ``i`` is ``1 - (1 - i/4096)**k`` rounded
        nearest-up to UQ1.12.  Entry 0 is 0 and entry 4096 is 4096 exactly; the table is
        non-decreasing.  Error against the real function: at most half an LSB (2**-13).
    """
    k_raw = int(k_raw)
    if not 1 <= k_raw <= cfg.ratio.raw_max:
        raise ValueError(f"k_raw {k_raw} outside 1..{cfg.ratio.raw_max} (k = 0 is a zero step)")
    return _table(k_raw, cfg.ratio_frac_bits)


def correct_opacity(
    alpha: np.ndarray, k: float | np.ndarray, cfg: CompositeConfig = DEFAULT
) -> np.ndarray:
    """Opacity correction ``a' = 1 - (1 - a)**k`` by table look-up.

    Parameters
    ----------
    alpha : array of int
        ``(n,)`` UQ1.12 raw opacities (values above 4096 saturate, counted).
    k : float or array of float
        ``dt / min(spacing)``: one value (parallel projection) or ``(n,)`` (perspective,
        per-ray).  Quantised nearest-up to UQ4.F; a value quantising to 0 raises.
    cfg : CompositeConfig

    Returns
    -------
    numpy.ndarray
        ``(n,)`` int64 UQ1.12.  One table per distinct quantised ``k`` (cached).
    """
    a = _saturate_unit(np.asarray(alpha, dtype=np.int64), ALPHA)
    if np.ndim(k) == 0:
        return correction_for(k, cfg)[a]
    kq = cfg.ratio.quantize(k)
    values, inverse = np.unique(kq, return_inverse=True)
    tables = np.stack([correction_table(int(v), cfg) for v in values])
    return tables[inverse.reshape(a.shape), a]


def correction_for(k: float, cfg: CompositeConfig = DEFAULT) -> np.ndarray:
    """The :func:`correction_table` of one exponent ``k = dt / min(spacing)`` (quantised
    nearest-up to UQ4.F; a value quantising to 0 raises)."""
    return correction_table(int(cfg.ratio.quantize(k)), cfg)


def _check_unit_inputs(rgb: np.ndarray, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return (
        _saturate_unit(np.asarray(rgb, dtype=np.int64), ALPHA),
        _saturate_unit(np.asarray(alpha, dtype=np.int64), ALPHA),
    )


def front_to_back(
    acc: np.ndarray,
    rays: np.ndarray,
    rgb: np.ndarray,
    alpha: np.ndarray,
    cfg: CompositeConfig = DEFAULT,
) -> None:
    """Front-to-back blend, in place: ``w = (1-A) a; C += w c; A += w``.

    Parameters
    ----------
    acc : numpy.ndarray
        ``(n_rays, 4)`` int64 UQ1.F accumulators (premultiplied RGB, A); updated in place.
    rays : array of int
        ``(n,)`` ray of each sample; each ray at most once per call.
    rgb : array of int
        ``(n, 3)`` UQ1.12 colours, *not* premultiplied.
    alpha : array of int
        ``(n,)`` UQ1.12 (already opacity-corrected) opacities.
    cfg : CompositeConfig
    """
    rgb, a = _check_unit_inputs(rgb, alpha)
    fmt = cfg.acc
    one = 1 << fmt.frac_bits
    rays = np.asarray(rays, dtype=np.int64)
    cur = np.take(acc, rays, axis=0)  # row gather; much faster than acc[rays] for (n, 4)
    code = ROUNDING_CODES[fmt.rounding]
    w = ftb_weight_raw(cur[:, 3], a, one, code)
    cur[:, :3] += ftb_colour_raw(w[:, None], rgb, code)
    cur[:, 3] += w
    _put_rows(acc, rays, _saturate_unit(cur, fmt))


def ftb_weight_raw(acc_alpha, alpha, one: int, code: int):
    """``w = round((1 - A) a)`` of :func:`front_to_back` (int64 arrays or scalars; ``one``
    is 1.0 of the accumulator, ``code`` its rounding's
    :data:`~hwsim.numerics.ROUNDING_CODES` entry)."""
    return round_shift_raw((one - acc_alpha) * alpha, _ALPHA_BITS, code)


def ftb_colour_raw(w, colour, code: int):
    """``round(w c)``, the colour increment of :func:`front_to_back`."""
    return round_shift_raw(w * colour, _ALPHA_BITS, code)


def _put_rows(acc: np.ndarray, rays: np.ndarray, rows: np.ndarray) -> None:
    """``acc[rays] = rows`` for a C-contiguous ``(n_rays, k)`` array, through a flat view
    (one 1-D scatter instead of a 2-D one; rays are distinct, so the order is moot)."""
    if not acc.flags.c_contiguous:
        acc[rays] = rows
        return
    k = acc.shape[1]
    flat = (rays[:, None] * k + np.arange(k)).ravel()
    acc.reshape(-1)[flat] = rows.ravel()


def back_to_front(
    acc: np.ndarray,
    rays: np.ndarray,
    rgb: np.ndarray,
    alpha: np.ndarray,
    cfg: CompositeConfig = DEFAULT,
) -> None:
    """Back-to-front blend, in place: ``C = a c + (1-a) C; A = a + (1-a) A``.

    Same arguments as :func:`front_to_back`; samples arrive farthest first.  Each channel
    is one rounding of the exact convex combination (error <= 2**-(F+1) per sample).
    """
    rgb, a = _check_unit_inputs(rgb, alpha)
    fmt = cfg.acc
    up = fmt.frac_bits - _ALPHA_BITS
    rays = np.asarray(rays, dtype=np.int64)
    cur = acc[rays]
    src = np.concatenate([rgb, np.full((a.size, 1), 1 << _ALPHA_BITS, dtype=np.int64)], axis=1)
    blended = btf_raw(cur, src, a[:, None], up, ROUNDING_CODES[fmt.rounding])
    acc[rays] = _saturate_unit(blended, fmt)


def btf_raw(acc, src, alpha, up: int, code: int):
    """One channel of :func:`back_to_front`: ``round((a s 2**up + (1 - a) C) / 2**12)``
    of a sample's channel ``s`` (UQ1.12 colour, or 4096 for opacity) over the accumulator
    ``C`` (UQ1.``12 + up``), int64 arrays or scalars; ``code`` the rounding's
    :data:`~hwsim.numerics.ROUNDING_CODES` entry."""
    return round_shift_raw(
        ((alpha * src) << up) + ((1 << _ALPHA_BITS) - alpha) * acc, _ALPHA_BITS, code
    )


def terminated(acc: np.ndarray, threshold: float, cfg: CompositeConfig = DEFAULT) -> np.ndarray:
    """Early-ray-termination mask: ``A >= threshold`` (threshold quantised nearest-up to
    UQ1.F).  ``threshold >= 1.0`` disables ERT (all False), as in the golden renderer,
    even for rays whose ``A`` reached exactly 1.0."""
    acc = np.asarray(acc, dtype=np.int64)
    if threshold >= 1.0:
        return np.zeros(acc.shape[0], dtype=bool)
    thr = int(cfg.acc.quantize(max(threshold, 0.0)))
    return acc[:, 3] >= thr


def mip(acc: np.ndarray, rays: np.ndarray, sample: np.ndarray) -> None:
    """Maximum-intensity projection, in place: ``acc[r] = max(acc[r], sample)`` (raw)."""
    np.maximum.at(acc, np.asarray(rays, dtype=np.int64), np.asarray(sample, dtype=np.int64))


def minip(acc: np.ndarray, rays: np.ndarray, sample: np.ndarray) -> None:
    """Minimum-intensity projection, in place: ``acc[r] = min(acc[r], sample)`` (raw)."""
    np.minimum.at(acc, np.asarray(rays, dtype=np.int64), np.asarray(sample, dtype=np.int64))


def xray(
    acc: np.ndarray,
    rays: np.ndarray,
    sample: np.ndarray,
    dt: float | np.ndarray,
    cfg: CompositeConfig = DEFAULT,
) -> None:
    """X-ray sum, in place: ``acc[r] += sample * dt``.

    Parameters
    ----------
    acc : numpy.ndarray
        ``(n_rays,)`` int64, format ``cfg.xray_acc`` (S + F fraction bits, saturating).
    rays : array of int
        ``(n,)``; repeats allowed.
    sample : array of int
        ``(n,)`` non-negative raw samples with S fraction bits.
    dt : float or array of float
        World step length, quantised nearest-up to UQ8.F; negative values raise
        ``ValueError``, values above 256 saturate (counted).
    cfg : CompositeConfig

    Notes
    -----
    The product is exact (< 2**40); all addends are non-negative, so saturating once after
    the sum equals saturating after every addition.  Error against ``sum(v dt)`` in real
    units: ``sum(v) * 2**-(F+1)`` from the weight quantisation only.
    """
    dt_arr = np.asarray(dt, dtype=np.float64)
    if (dt_arr < 0).any():
        raise ValueError("xray: negative dt")
    s = np.asarray(sample, dtype=np.int64)
    if (s < 0).any():
        raise ValueError("xray: negative samples")
    w = cfg.xray_dt.quantize(dt_arr)
    tmp = np.zeros_like(acc)
    np.add.at(tmp, np.asarray(rays, dtype=np.int64), s * w)
    acc[:] = cfg.xray_acc.saturate(np.minimum(acc + tmp, cfg.xray_acc.raw_max + 1))


def iso_hit(sample: np.ndarray, threshold: int) -> np.ndarray:
    """First-hit test of iso mode: ``sample >= threshold`` (both raw, same format).  The
    caller keeps a per-ray done mask and shades only the first hit."""
    return np.asarray(sample, dtype=np.int64) >= np.int64(threshold)


def to_output(acc: np.ndarray, cfg: CompositeConfig = DEFAULT) -> np.ndarray:
    """UQ1.F accumulators to unorm ``output_bits``: ``round(acc (2**b - 1) / 2**F)``,
    nearest-up; 1.0 -> ``2**b - 1``, error <= half an output LSB."""
    raw = _saturate_unit(np.asarray(acc, dtype=np.int64), cfg.acc)
    top = (1 << cfg.output_bits) - 1
    return round_shift(raw * top, cfg.acc_frac_bits, "nearest-up")


def output_to_float(out: np.ndarray, cfg: CompositeConfig = DEFAULT) -> np.ndarray:
    """Unorm pixels to float64 in [0, 1]: ``out / (2**b - 1)``."""
    return np.asarray(out, dtype=np.float64) / ((1 << cfg.output_bits) - 1)


def ftb_error_bound(n: int, cfg: CompositeConfig = DEFAULT) -> tuple[float, float]:
    """``(bound on |dA|, bound on |dC|)`` of front-to-back compositing of ``n`` samples
    against float64 compositing of the same quantised inputs: ``(n h, 3 n h)`` with
    ``h = 2**-(F+1)``.  Derivation in docs/units/composite-crop-skew.md."""
    h = 2.0 ** -(cfg.acc_frac_bits + 1)
    return n * h, 3 * n * h
