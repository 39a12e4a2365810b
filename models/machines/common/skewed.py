"""The Cube skewed volume memory (Cube-1's cubic frame buffer, Cube-3's volume memory):
n memory modules, voxel ``(x, y, z)`` in module ``(x + y + z) mod n`` at address
``(z div n, y, x)``.

# Ref: Kaufman, "Memory Organization for a Cubic Frame Buffer", Eurographics 1986
#      (abstract) [V]: n modules, module k holds the diagonal planes whose index is k mod n,
#      so any axis-parallel beam of n voxels meets n different modules; the formula and the
#      (y, x) address (z is implied by the module when the volume is n deep) are [I]
#      (architectures.md 1.2); ``z div n`` extends it to volumes deeper than n [I].

A beam is read in as many memory cycles as the most voxels it has in one module (one,
for an axis-parallel beam no longer than n: the skewing's point).  The beam arrives in
module order, rotated by ``(x + y) mod n`` for a z-beam; each module's word carries its
address, which with the module gives the voxel back (the de-skew) [I].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.units.skew import cube4_module

__all__ = ["CubicFrameBuffer", "beam_cycles"]


def beam_cycles(module: np.ndarray, beam: np.ndarray, n_beams: int, modules: int) -> np.ndarray:
    """Memory cycles of each beam: the most of its voxels in one module (``module`` and
    ``beam`` per voxel read; beams with no voxel take none)."""
    if module.size == 0:
        return np.zeros(n_beams, np.int64)
    per = np.bincount(beam * modules + module, minlength=n_beams * modules)
    return per.reshape(n_beams, modules).max(axis=1).astype(np.int64)


@dataclass
class CubicFrameBuffer:
    """The volume written into ``modules`` skewed memory modules (the host's write).

    ``stuck_module``: a module whose reads return zero (fault injection).
    """

    words: np.ndarray  # (modules, ceil(nz / modules) * ny * nx) voxel values
    shape: tuple[int, int, int]  # (nz, ny, nx)
    stuck_module: int | None = None

    @classmethod
    def write(cls, data: np.ndarray, modules: int, stuck_module: int | None = None):
        nz, ny, nx = data.shape
        z, y, x = np.indices(data.shape).reshape(3, -1)
        words = np.zeros((modules, -(-nz // modules) * ny * nx), dtype=data.dtype)
        words[cube4_module(x, y, z, modules), ((z // modules) * ny + y) * nx + x] = data.ravel()
        return cls(words, (nz, ny, nx), stuck_module)

    @property
    def modules(self) -> int:
        return self.words.shape[0]

    def module_of(self, zyx: np.ndarray) -> np.ndarray:
        z, y, x = zyx.T
        return cube4_module(x, y, z, self.modules)

    def read(self, zyx: np.ndarray) -> np.ndarray:
        """The words at voxels ``zyx`` (int ``(k, 3)``), as the modules return them."""
        module = self.module_of(zyx)
        z, y, x = zyx.T
        _, ny, nx = self.shape
        out = self.words[module, ((z // self.modules) * ny + y) * nx + x]
        if self.stuck_module is not None:
            out = np.where(module == self.stuck_module, 0, out).astype(out.dtype)
        return out
