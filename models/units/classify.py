"""Classification: a lookup table from sample value to RGBA, and gradient-magnitude modulation.

# Ref: architectures.md section 3 (VolumePro 500: 4096 entries, RGB 8-bit, alpha 12-bit;
#      8-bit voxels index it as value x 16; opacity modulated by gradient magnitude
#      through a table); section 4 (VolumePro 1000: 4096 or 256 entries).

Storage is unorm (``2**n - 1`` means 1.0).  Read-out expands to the pipeline's UQ1.12
(``4096`` is exactly 1.0) by ``round(x * 4096 / (2**n - 1))``, a constant multiply in
hardware, so 0 and full scale are exact.  Entry ``i`` stands for raw voxel value
``i * 2**B / entries``; a sample indexes the nearest entry (round half up).

Error against the float transfer function: half an entry step times the function's
largest slope (index rounding) plus ``2**-(n+1)`` (storage) plus ``2**-13`` (expansion).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hwsim.numerics import round_shift_raw
from hwsim.spec.transfer import TransferFunction

__all__ = [
    "ClassifyConfig",
    "Lut",
    "build_lut",
    "lut_index",
    "lut_index_raw",
    "gm_index_raw",
    "scale_alpha_raw",
    "classify",
    "classify_voxels",
    "expand",
    "build_gm_table",
    "gm_scale",
    "gm_index",
    "modulate",
    "LATENCY",
    "II",
]

#: Cycles: the RTL's stage plan (rtl/classify.py STAGES): index, SRAM read, expansion,
#: modulation, so every stage meets a 125 MHz clock at 0.35 um by the project's depth
#: estimate (issue 34).  architectures.md 9.3's "LUT 1-2" [I] held only with the
#: expansion and the modulation multiply in one stage (~60 gates deep, ~88 MHz).
LATENCY = 4
II = 1
ONE = 1 << 12  # 1.0 in UQ1.12
_GM_SCALE_BITS = 24


@dataclass(frozen=True, kw_only=True)
class ClassifyConfig:
    """LUT geometry and storage widths (defaults: VolumePro 500, [V])."""

    entries: int = 4096
    color_bits: int = 8
    alpha_bits: int = 12
    gm_entries: int = 64

    def __post_init__(self) -> None:
        if self.entries & (self.entries - 1) or not 2 <= self.entries <= 65536:
            raise ValueError("classify.entries must be a power of two, 2..65536")
        if not 1 <= self.color_bits <= 12 or not 1 <= self.alpha_bits <= 12:
            raise ValueError("classify color_bits and alpha_bits: 1..12")
        if not 2 <= self.gm_entries <= 4096:
            raise ValueError("classify.gm_entries: 2..4096")


@dataclass(frozen=True)
class Lut:
    """``rgb (entries, 3)`` and ``alpha (entries,)`` as stored (unorm), plus their UQ1.12
    read-out values."""

    rgb: np.ndarray
    alpha: np.ndarray
    rgb12: np.ndarray
    alpha12: np.ndarray


def expand(unorm: np.ndarray, bits: int) -> np.ndarray:
    """Unorm ``bits`` to UQ1.12, rounding half up: 0 -> 0, full scale -> 4096."""
    full = (1 << bits) - 1
    return (np.asarray(unorm, dtype=np.int64) * (2 * ONE) + full) // (2 * full)


def build_lut(
    tf: TransferFunction,
    to_value: Callable[[np.ndarray], np.ndarray],
    voxel_bits: int,
    cfg: ClassifyConfig,
) -> Lut:
    """Quantise ``tf`` into the table (host side)."""
    raw = np.arange(cfg.entries) * (2.0**voxel_bits / cfg.entries)
    rgba = tf.classify(to_value(raw))
    cmax, amax = (1 << cfg.color_bits) - 1, (1 << cfg.alpha_bits) - 1
    rgb = np.floor(rgba[:, :3] * cmax + 0.5).astype(np.int64)
    alpha = np.floor(rgba[:, 3] * amax + 0.5).astype(np.int64)
    return Lut(rgb, alpha, expand(rgb, cfg.color_bits), expand(alpha, cfg.alpha_bits))


def lut_index(
    sample: np.ndarray, voxel_bits: int, sample_frac_bits: int, cfg: ClassifyConfig
) -> np.ndarray:
    """The entry nearest a sample (``sample_frac_bits`` fraction bits), clamped."""
    shift = voxel_bits + sample_frac_bits - int(np.log2(cfg.entries))
    return lut_index_raw(np.asarray(sample, dtype=np.int64), shift, cfg.entries)


def lut_index_raw(sample, shift: int, entries: int):
    """The arithmetic of :func:`lut_index` on int64 arrays or scalars (compiled kernels
    call it too): ``clamp(round(sample / 2**shift), 0, entries - 1)``, nearest-up."""
    return np.minimum(np.maximum(round_shift_raw(sample, shift, 1), 0), entries - 1)


def classify(
    sample: np.ndarray, lut: Lut, voxel_bits: int, sample_frac_bits: int, cfg: ClassifyConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Post-classification: ``(rgb (n, 3), alpha (n,))`` in UQ1.12."""
    i = lut_index(sample, voxel_bits, sample_frac_bits, cfg)
    return np.take(lut.rgb12, i, axis=0), lut.alpha12[i]  # np.take: fast row gather


def classify_voxels(
    raw: np.ndarray, lut: Lut, voxel_bits: int, cfg: ClassifyConfig
) -> list[np.ndarray]:
    """Pre-classification: raveled UQ1.12 ``[r, g, b, a]`` arrays of every voxel."""
    i = lut_index(np.asarray(raw, dtype=np.int64).ravel(), voxel_bits, 0, cfg)
    return [lut.rgb12[i, 0], lut.rgb12[i, 1], lut.rgb12[i, 2], lut.alpha12[i]]


def build_gm_table(
    tf: TransferFunction, max_magnitude: float, cfg: ClassifyConfig, *, illumination=False
) -> np.ndarray:
    """Opacity factors (UQ1.12) at ``gm_entries`` magnitudes from 0 to ``max_magnitude``
    (value units per world unit); with ``illumination``, the diffuse and specular light
    factors of the same magnitudes (the second table, indexed alike)."""
    mags = np.linspace(0.0, max_magnitude, cfg.gm_entries)
    factor = tf.illumination_factor if illumination else tf.gradient_factor
    return np.floor(factor(mags) * ONE + 0.5).astype(np.int64)


def gm_scale(units_per_magnitude: float, max_magnitude: float, cfg: ClassifyConfig) -> int:
    """Host constant turning an integer magnitude into a table index: UQ0.24 of
    ``units_per_magnitude * (gm_entries - 1) / max_magnitude``."""
    k = units_per_magnitude * (cfg.gm_entries - 1) / max_magnitude if max_magnitude > 0 else 0.0
    return int(np.floor(k * (1 << _GM_SCALE_BITS) + 0.5))


def gm_index(magnitude: np.ndarray, scale: int, cfg: ClassifyConfig) -> np.ndarray:
    """Table index of integer magnitudes: ``round(magnitude * scale / 2**24)``, clamped."""
    return gm_index_raw(np.asarray(magnitude, dtype=np.int64), scale, cfg.gm_entries)


def gm_index_raw(magnitude, scale: int, entries: int):
    """The arithmetic of :func:`gm_index` on int64 arrays or scalars."""
    idx = round_shift_raw(magnitude * scale, _GM_SCALE_BITS, 1)
    return np.minimum(np.maximum(idx, 0), entries - 1)


def modulate(alpha: np.ndarray, index: np.ndarray, table: np.ndarray) -> np.ndarray:
    """``alpha * table[index]`` in UQ1.12, rounded half up."""
    return scale_alpha_raw(alpha, table[index])


def scale_alpha_raw(alpha, factor):
    """``round(alpha * factor / 2**12)``, nearest-up, of UQ1.12 values (int64 arrays or
    scalars): gradient-magnitude modulation, and the cut-plane factor in the back end."""
    return round_shift_raw(alpha * factor, 12, 1)
