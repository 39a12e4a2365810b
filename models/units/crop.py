"""Crop box and thick oblique cut planes, bit-exact in fixed point.

# Ref: architectures.md section 3 (VolumePro 500: box cropping from three axis-aligned
#      slabs, and one oblique cut plane ``VLICutPlane(A, B, C, D, thickness, falloff)``,
#      [V] FAQ / VLI), section 4 (VolumePro 1000: up to 4 cut planes, [V] vli.h) and 9.1
#      (cut/crop unit, plane equation in fixed point, [I]); golden:
#      hwsim/golden/shading.py ``crop_keep`` and ``cut_factor``.

Crop: inclusive index limits and ``invert``, as the golden ``crop_keep``.  Fixed-point
positions (``frac_bits`` given) compare with ``lo_raw = ceil(lo 2**F)`` and ``hi_raw =
floor(hi 2**F)``: exactly the golden decision on the same positions (comparators only).

Cut plane (formats named ``cut.*``, all nearest-up)::

    p      cut.pos      SQ12.8   world position, relative to the volume centre
    n      cut.normal   SQ1.12   unit normal (normalised on the host, then quantised)
    d      cut.dist     SQ12.8   n.p - offset: exact 20-fraction-bit dot product, rounded
    h      cut.dist     SQ12.8   thickness / 2 (host constant)
    r      cut.inv      UQ16.16  1 / falloff (host constant)
    f      cut.factor   UQ1.12   clip(1 - (|d| - h) r, 0, 1); 0/1 step if falloff == 0

Planes multiply their factors (UQ1.12, one rounding each).  Error against the golden
factor (see :func:`cut_error_bound`): the distance error ``e_d <= sqrt(3) 2**-9 (1 +
3 2**-13) + |p|_1 2**-13 + 3 2**-9`` times ``1/falloff + 2**-17``, plus ``falloff 2**-17``
(the reciprocal), plus ``2**-13`` (ramp rounding), per plane, plus ``2**-13`` per product.
With ``falloff == 0`` the factor is exact wherever the golden distance is farther than
``e_d`` from the slab's edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hwsim.numerics import FixedFormat, round_shift, sq, uq
from hwsim.spec.scene import CropSpec, CutPlane

__all__ = [
    "II",
    "LATENCY",
    "CutConfig",
    "crop_keep",
    "cut_error_bound",
    "cut_factor",
    "distance_error_bound",
    "FACTOR",
]

#: Cycles, [I] from architectures.md 9.3 (no published figure): dot product 1, |d| - h and
#: ramp multiply 1; the crop comparators run in parallel.
LATENCY = 2
#: One sample per clock.
II = 1

_F12 = 12
_ONE = 1 << _F12


@dataclass(frozen=True, kw_only=True)
class CutConfig:
    """Cut-plane widths (defaults: VolumePro 500, one plane; widths are [I]).

    Parameters
    ----------
    pos_frac_bits : int
        Fraction bits of world positions (SQ12.F).
    normal_frac_bits : int
        Fraction bits of the plane normal (SQ1.F).
    dist_frac_bits : int
        Fraction bits of the signed distance (SQ12.F).
    inv_frac_bits : int
        Fraction bits of ``1 / falloff`` (UQ16.F).
    max_planes : int
        1 on VolumePro 500, 4 on VolumePro 1000.
    """

    pos_frac_bits: int = 8
    normal_frac_bits: int = 12
    dist_frac_bits: int = 8
    inv_frac_bits: int = 16
    max_planes: int = 1

    def __post_init__(self) -> None:
        for f in (self.pos_frac_bits, self.normal_frac_bits, self.dist_frac_bits):
            if not 1 <= f <= 16:
                raise ValueError("cut widths must be 1..16 fraction bits")
        if not 1 <= self.inv_frac_bits <= 20 or self.max_planes < 1:
            raise ValueError("inv_frac_bits 1..20, max_planes >= 1")

    @property
    def pos(self) -> FixedFormat:
        return sq("cut.pos", 12, self.pos_frac_bits)

    @property
    def normal(self) -> FixedFormat:
        return sq("cut.normal", 1, self.normal_frac_bits)

    @property
    def dist(self) -> FixedFormat:
        return sq("cut.dist", 12, self.dist_frac_bits)

    @property
    def inv(self) -> FixedFormat:
        return uq("cut.inv", 16, self.inv_frac_bits)


#: The opacity factor leaving the unit (UQ1.12, 4096 = 1.0).
FACTOR = uq("cut.factor", 1, _F12)
DEFAULT = CutConfig()


def crop_keep(zyx: np.ndarray, crop: CropSpec, frac_bits: int | None = None) -> np.ndarray:
    """Mask of samples the crop box keeps.

    Parameters
    ----------
    zyx : numpy.ndarray
        ``(n, 3)`` positions in voxel index coordinates: float, or raw integers with
        ``frac_bits`` fraction bits.
    crop : CropSpec
        Inclusive slab limits per axis (``None``: unlimited), ``mode`` (sub-volume,
        cross or fence: inside 3, 2 or 1 of the slabs) and ``invert``.
    frac_bits : int, optional
        Set when ``zyx`` is fixed point.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` bool, identical to the golden ``crop_keep`` on the same positions.
    """
    zyx = np.asarray(zyx)
    slabs = np.zeros(zyx.shape[0], dtype=np.int64)
    for col, limits in enumerate((crop.z, crop.y, crop.x)):
        if limits is None:
            slabs += 1
            continue
        lo, hi = limits
        if frac_bits is None:
            slabs += (zyx[:, col] >= lo) & (zyx[:, col] <= hi)
        else:
            scale = float(1 << frac_bits)
            lo_raw, hi_raw = int(np.ceil(lo * scale)), int(np.floor(hi * scale))
            c = zyx[:, col].astype(np.int64)
            slabs += (c >= lo_raw) & (c <= hi_raw)
    # Three comparators per axis feed a 2-bit count of slabs hit; the mode picks the
    # threshold (sub-volume 3, cross 2, fence 1) and invert the complement.
    inside = slabs >= crop.slabs_needed
    return ~inside if crop.invert else inside


def _plane_constants(plane: CutPlane, cfg: CutConfig) -> tuple[np.ndarray, int, int, int]:
    normal = np.asarray(plane.normal, dtype=np.float64)
    norm = float(np.linalg.norm(normal))
    if not norm > 0:
        raise ValueError("cut plane normal must be non-zero")
    n_raw = cfg.normal.quantize(normal / norm)
    off = int(cfg.dist.quantize(plane.offset))
    half = int(cfg.dist.quantize(plane.thickness / 2.0))
    inv = int(cfg.inv.quantize(1.0 / plane.falloff)) if plane.falloff > 0 else 0
    return n_raw, off, half, inv


def cut_factor(
    p_world: np.ndarray, planes: tuple[CutPlane, ...], cfg: CutConfig = DEFAULT
) -> np.ndarray:
    """UQ1.12 opacity factor of thick cut planes.

    Parameters
    ----------
    p_world : numpy.ndarray
        ``(n, 3)`` float64 world points ``(x, y, z)`` relative to the volume centre
        (quantised to ``cut.pos`` on entry; outside SQ12 saturates, counted).
    planes : tuple of CutPlane
        At most ``cfg.max_planes``.
    cfg : CutConfig

    Returns
    -------
    numpy.ndarray
        ``(n,)`` int64 UQ1.12; ``> 0`` means the sample is kept.
    """
    if len(planes) > cfg.max_planes:
        raise ValueError(f"{len(planes)} cut planes; this machine has {cfg.max_planes}")
    p = cfg.pos.quantize(np.asarray(p_world, dtype=np.float64))
    factor = np.full(p.shape[0], _ONE, dtype=np.int64)
    shift = cfg.pos_frac_bits + cfg.normal_frac_bits - cfg.dist_frac_bits
    for plane in planes:
        n_raw, off, half, inv = _plane_constants(plane, cfg)
        dot = p @ n_raw  # exact: |p| < 2**20, |n| <= 2**12, three terms
        d = cfg.dist.saturate(round_shift(dot, shift, "nearest-up") - off)
        beyond = np.abs(d) - half
        if plane.falloff > 0:
            # clip first: beyond >= 2**20 already means factor 0, and the product stays < 2**53
            b = np.clip(beyond, 0, 1 << 20)
            ramp = round_shift(b * inv, cfg.dist_frac_bits + cfg.inv_frac_bits - _F12, "nearest-up")
            f = np.clip(_ONE - ramp, 0, _ONE)
        else:
            f = np.where(beyond <= 0, _ONE, 0).astype(np.int64)
        if plane.invert:
            f = _ONE - f
        factor = round_shift(factor * f, _F12, "nearest-up")
    return factor


def cut_error_bound(
    p_world: np.ndarray, planes: tuple[CutPlane, ...], cfg: CutConfig = DEFAULT
) -> np.ndarray:
    """Per-point bound on ``|cut_factor / 4096 - golden cut_factor|`` for planes with a
    positive fall-off (with no fall-off the bound is 1 near the slab edge, 0 elsewhere:
    see :func:`distance_error_bound`)."""
    total = np.zeros(np.asarray(p_world).shape[0])
    for plane in planes:
        e_d = distance_error_bound(p_world, cfg)
        if plane.falloff > 0:
            e_r = 2.0 ** -(cfg.inv_frac_bits + 1)
            e = e_d * (1.0 / plane.falloff + e_r) + plane.falloff * e_r + 2.0**-13
        else:
            e = np.ones_like(e_d)
        total += np.minimum(e, 1.0) + 2.0**-13
    return total


def distance_error_bound(p_world: np.ndarray, cfg: CutConfig = DEFAULT) -> np.ndarray:
    """Per-point bound on the error of the signed distance ``|d| - h`` (world units):
    position rounding through the quantised normal, the normal's rounding times
    ``|p|_1``, and three roundings at the distance's LSB (dot, offset, half thickness)."""
    p = np.asarray(p_world, dtype=np.float64)
    e_pos = 2.0 ** -(cfg.pos_frac_bits + 1)
    e_n = 2.0 ** -(cfg.normal_frac_bits + 1)
    e_dist = 2.0 ** -(cfg.dist_frac_bits + 1)
    return (
        np.sqrt(3.0) * (1.0 + 3.0 * e_n) * e_pos
        + (np.abs(p).sum(axis=1) + 3 * e_pos) * e_n
        + 3 * e_dist
    )
