"""Skewed volume memory: Cube-4's diagonal skew and VolumePro 500's two-level mini-blocks.

# Ref: architectures.md section 1.2 (Cube-4: module ``(x + y + z) mod P`` [R hi];
#      in-module address ``(z n^2 + y n + x) div P`` [I]) and section 3 (US 6,266,733
#      "Two-level mini-block storage system": 2x2x2 mini-blocks skewed across memory
#      modules, then across SDRAM banks inside a module so consecutive mini-block reads
#      alternate banks [V abstract]; every formula for the VolumePro 500 below is [I]).

Cube-4: a run of P consecutive voxels along any axis changes ``x + y + z`` by one per
step, so it touches P distinct modules (one voxel per module per clock).  The in-module
address uses a row pitch ``nx = ceil(n / P) P`` (``= n`` when P divides n, the formula of
architectures.md 1.2): an aligned run of P x-voxels then shares one address, and
``(module, address)`` is a bijection for every ``n`` ([I] generalisation; the padding
words are unused).

VolumePro 500 [I]: mini-block ``b = (x, y, z) // 2`` with ``s = bx + by + bz``::

    module  = s mod M
    bank    = (s div M) mod K
    address = 8 * (Lb div (M K)) + o,   Lb = (bz nb + by) nbx + bx,  nbx = ceil(nb / (M K)) M K
    o       = 4 (z & 1) + 2 (y & 1) + (x & 1)     (position in the burst of 8)

Neighbouring mini-blocks along any axis are in different modules; the next mini-block a
module receives along any axis has ``s`` larger by M, hence the next bank.  Addresses fit
int64 for any volume the tests use (1024^3: 2**27 words per module at P = 8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "II",
    "LATENCY",
    "SkewConfig",
    "beam_is_conflict_free",
    "block_miniblock",
    "cube4_address",
    "cube4_address_zyx",
    "cube4_module",
    "cube4_voxel",
    "vp500_miniblock",
    "vp500_voxel",
]

#: Cycles: the RTL's stage plan (rtl/skew.py STAGES: row, linear, address), pipelined so
#: every stage meets a 125 MHz clock at 0.35 um by the project's depth estimate (issue 34;
#: architectures.md 9.1 / 9.3's "de-skew 1" [I] held only as a 52-gate-deep stage, ~102
#: MHz); SDRAM CAS latency belongs to the memory model.
LATENCY = 3
#: One access per module per clock.
II = 1


@dataclass(frozen=True, kw_only=True)
class SkewConfig:
    """Memory organisation (defaults: VolumePro 500).

    Parameters
    ----------
    modules : int
        Memory modules (4 on VolumePro 500 [R hi]: one per pipeline).
    banks : int
        SDRAM banks per module (4, [I] typical SDRAM).
    max_size : int
        Largest voxels per axis in one pass (256 on VolumePro 500, RTViz FAQ [V]).
    """

    modules: int = 4
    banks: int = 4
    max_size: int = 256

    def __post_init__(self) -> None:
        if self.modules < 1 or self.banks < 1 or self.max_size < 1:
            raise ValueError("modules, banks and max_size must be >= 1")


def _i64(*a):
    return tuple(np.asarray(v, dtype=np.int64) for v in a)


def _pitch(n: int, p: int) -> int:
    return -(-n // p) * p


def cube4_module(x, y, z, P: int) -> np.ndarray:
    """Cube-4 memory module ``(x + y + z) mod P`` of voxels (int64)."""
    x, y, z = _i64(x, y, z)
    return (x + y + z) % P


def cube4_address(x, y, z, n: int, P: int) -> np.ndarray:
    """Word address inside the voxel's module: ``(z n nx + y nx + x) div P`` with row pitch
    ``nx = ceil(n / P) P`` (``= n`` when P divides n).  int64 throughout."""
    x, y, z = _i64(x, y, z)
    nx = _pitch(n, P)
    return ((z * n + y) * nx + x) // P


def cube4_voxel(module, address, n: int, P: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of ``(cube4_module, cube4_address)``: voxel ``(x, y, z)``.  Pairs that fall in
    row padding (P not dividing n) give ``x >= n``."""
    module, address = _i64(module, address)
    nx = _pitch(n, P)
    row, x0 = np.divmod(address * P, nx)
    z, y = np.divmod(row, n)
    x = x0 + (module - (x0 + y + z)) % P
    return x, y, z


def vp500_miniblock(
    x, y, z, n: int, modules: int = 4, banks: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """VolumePro 500 two-level mini-block skew ([I] formulas, see module docstring).

    Parameters
    ----------
    x, y, z : array of int
        Voxel coordinates, ``0 <= x, y, z < n``.
    n : int
        Voxels per axis.
    modules, banks : int

    Returns
    -------
    module, bank, address : numpy.ndarray
        int64; ``address`` is the word inside ``(module, bank)``, 8 words per mini-block.
    """
    x, y, z = _i64(x, y, z)
    bx, by, bz = x >> 1, y >> 1, z >> 1
    s = bx + by + bz
    mk = modules * banks
    nb = -(-n // 2)
    lb = (bz * nb + by) * _pitch(nb, mk) + bx
    o = ((z & 1) << 2) | ((y & 1) << 1) | (x & 1)
    return s % modules, (s // modules) % banks, ((lb // mk) << 3) | o


def block_miniblock(
    x, y, z, n: int, modules: int, banks: int, columns: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The naive contrast to :func:`vp500_miniblock`: the same 2x2x2 mini-blocks and module
    skew ``(bx + by + bz) mod M``, but no bank skew.  Each module stores its mini-blocks
    linearly and the bank is the top address bits (a bank holds ``1/K`` of the module,
    rounded up to whole rows of ``columns`` words): the layout a controller gets without
    the second skew level.  ``n`` even; returns int64 (module, bank, word in the bank)."""
    x, y, z = _i64(x, y, z)
    nb = n // 2
    bx, by, bz = x >> 1, y >> 1, z >> 1
    pitch = _pitch(nb, modules)
    o = ((z & 1) << 2) | ((y & 1) << 1) | (x & 1)
    linear = 8 * (((bz * nb + by) * pitch + bx) // modules) + o
    per_bank = -(-int(8 * nb * nb * pitch // modules) // banks)
    per_bank = -(-per_bank // columns) * columns
    bank, address = np.divmod(linear, per_bank)
    return (bx + by + bz) % modules, bank, address


def vp500_voxel(
    module, bank, address, n: int, modules: int = 4, banks: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`vp500_miniblock`: voxel ``(x, y, z)``."""
    module, bank, address = _i64(module, bank, address)
    mk = modules * banks
    nb = -(-n // 2)
    row, bx0 = np.divmod((address >> 3) * mk, _pitch(nb, mk))
    bz, by = np.divmod(row, nb)
    c = (bank * modules + module) % mk  # s mod (M K)
    bx = bx0 + (c - (bx0 + by + bz)) % mk
    o = address & 7
    return 2 * bx + (o & 1), 2 * by + ((o >> 1) & 1), 2 * bz + (o >> 2)


def beam_is_conflict_free(P: int, n: int, axis: int) -> bool:
    """Whether every run of ``min(P, n)`` consecutive voxels along ``axis`` (0 = x, 1 = y,
    2 = z) of an ``n``-cube hits distinct Cube-4 modules.

    Every beam is checked up to its residue ``(u + v) mod P`` of the other two coordinates,
    which is all the module function sees: beams with ``u, v < min(n, P)`` cover every
    residue a real beam can have.
    """
    if axis not in (0, 1, 2):
        raise ValueError("axis is 0 (x), 1 (y) or 2 (z)")
    m = min(n, P)
    u, v = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    u, v = u.ravel()[:, None], v.ravel()[:, None]
    t = np.arange(n)[None, :]
    coords = [u, v]
    coords.insert(axis, t)
    mods = cube4_module(*np.broadcast_arrays(*coords), P)
    runs = np.lib.stride_tricks.sliding_window_view(mods, m, axis=1)
    runs = np.sort(runs, axis=-1)
    return bool(np.all(np.diff(runs, axis=-1) != 0))


def cube4_address_zyx(z, y, x, shape: tuple[int, int, int], P: int) -> np.ndarray:
    """:func:`cube4_address` for a box ``shape = (nz, ny, nx)``: ``((z ny + y) nxp + x) div P``
    with row pitch ``nxp = ceil(nx / P) P``; a bijection with :func:`cube4_module` per row."""
    x, y, z = _i64(x, y, z)
    _, ny, nx = shape
    return ((z * ny + y) * _pitch(nx, P) + x) // P
