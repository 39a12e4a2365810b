"""Skewed volume memory: Cube-4's diagonal skew and VolumePro 500's two-level mini-blocks.

# Ref: architectures.md section 1.2 (Kaufman 1986; Cube-4: module (x + y + z) mod P,
#      [R hi]; in-module address (z n^2 + y n + x) div P, [I]) and section 3
#      (US 6,266,733: 2x2x2 mini-blocks skewed across modules, then across SDRAM banks,
#      [V] abstract; the exact formulas below are [I]).

Cube-4: any run of P consecutive voxels along any axis changes ``x + y + z`` by one per
step, so it touches P distinct modules: one voxel per module per clock.

VolumePro 500 (inferred form): mini-block ``(bx, by, bz) = (x, y, z) // 2`` lives in
module ``(bx + by + bz) mod M``; inside the module consecutive mini-blocks alternate
banks ``((bx + by + bz) // M) mod K``, so a burst of one mini-block (8 voxels) never
waits for its own bank.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "cube4_module",
    "cube4_address",
    "cube4_voxel",
    "vp500_miniblock",
    "beam_is_conflict_free",
    "LATENCY",
    "II",
]

LATENCY = 1  # cycles, [I] address generation and de-skew (architectures.md 9.1)
II = 1


def cube4_module(x, y, z, p: int):
    """Memory module of voxel ``(x, y, z)`` with ``p`` modules."""
    return (np.asarray(x) + y + z) % p


def cube4_address(x, y, z, n: int, p: int):
    """Address inside its module: ``(z n^2 + y n + x) div p`` (a bijection with the module
    when ``p`` divides ``n``)."""
    return (np.asarray(z, dtype=np.int64) * n * n + np.asarray(y, dtype=np.int64) * n + x) // p


def cube4_voxel(module, address, n: int, p: int):
    """Inverse of (module, address) when ``p`` divides ``n``: voxel ``(x, y, z)``."""
    base = np.asarray(address, dtype=np.int64) * p
    z, rem = np.divmod(base, n * n)
    y, x0 = np.divmod(rem, n)
    x = x0 + (np.asarray(module) - (x0 + y + z)) % p
    return x, y, z


def vp500_miniblock(x, y, z, modules: int = 4, banks: int = 4):
    """``(module, bank, index)`` of a voxel: its mini-block's module and SDRAM bank, and the
    voxel's index 0..7 inside the 2x2x2 mini-block."""
    bx, by, bz = np.asarray(x) // 2, np.asarray(y) // 2, np.asarray(z) // 2
    s = bx + by + bz
    index = (np.asarray(z) % 2) * 4 + (np.asarray(y) % 2) * 2 + np.asarray(x) % 2
    return s % modules, (s // modules) % banks, index


def beam_is_conflict_free(p: int, n: int, axis: int) -> bool:
    """Whether every run of ``p`` consecutive voxels along ``axis`` of an ``n``-cube hits
    ``p`` distinct Cube-4 modules."""
    coords = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    for start in range(max(n - p + 1, 1)):
        run = coords[coords[:, axis] == start]
        mods = []
        for k in range(min(p, n)):
            c = run.copy()
            c[:, axis] += k
            mods.append(cube4_module(c[:, 0], c[:, 1], c[:, 2], p))
        mods = np.sort(np.stack(mods, axis=1), axis=1)
        if mods.shape[1] > 1 and not np.all(np.diff(mods, axis=1) != 0):
            return False
    return True
