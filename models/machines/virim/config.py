"""VIRIM's ``[buffers]`` table, its board assignment and its board schedule.

# Ref: shared/docs/reference/000_d6a752d96745b32a.txt (VIRIM [72]: a resampling unit using
#      lookup tables for the interpolation schemes, then a ray-casting unit with
#      programmable lighting; parallel and perspective; 256x256x128 at 10 fps on 16
#      boards [V]); Günther et al., EGGH 1994 abstract [V]; de Boer et al., EGGH 1996
#      abstract (the volume duplicated on the modules [V]).  docs/architectures.md
#      ("VIRIM"): what is inferred.

Each board (``[pipeline] count``) holds the whole volume [V] and renders the image rows
dealt to it round robin [I].  On a board the resampling unit produces a ray's samples at
``resample_clocks`` each into one of ``ray_buffers`` ray buffers; one of ``raycasters``
ray-casting processors takes a ray as soon as its first sample is out and spends
``raycast_clocks`` per sample (its programmable lighting), never overtaking the
resampler.  The buffer is free when the processor has finished the ray.
"""

from __future__ import annotations

import heapq

import numpy as np

from hwsim.core.models import Schema, integer, validate
from hwsim.spec.arch import ArchConfig

__all__ = ["LATENCY", "VirimBuffers", "board_of", "board_schedule", "buffers_of"]

#: Clocks from a ray's last sample to its pixel at the host [I].
LATENCY = 16


class VirimBuffers(Schema):
    """``[buffers]`` of a VIRIM board."""

    resample_clocks: integer(1, 64) = 1
    raycasters: integer(1, 64) = 2
    raycast_clocks: integer(1, 256) = 4
    ray_buffers: integer(1, 1024) = 2


def buffers_of(arch: ArchConfig) -> VirimBuffers:
    return validate(arch.buffers, VirimBuffers, arch.source, prefix="buffers")


def board_of(ray_ids: np.ndarray, width: int, boards: int) -> np.ndarray:
    """The board rendering each ray: image rows dealt round robin."""
    return (ray_ids // max(width, 1)) % boards


def board_schedule(samples: np.ndarray, b: VirimBuffers) -> tuple[int, int, int]:
    """One board's rays (``samples`` each, in order) through its resampler, ray buffers
    and ray casters: (end clock, resampler busy clocks, ray-caster busy clocks)."""
    rc, cc = b.resample_clocks, b.raycast_clocks
    casters = [0] * b.raycasters
    buffers = [0] * b.ray_buffers
    resampler = end = 0
    for n in samples.tolist():
        start = max(resampler, heapq.heappop(buffers))
        resampler = start + n * rc
        cast = max(heapq.heappop(casters), start + rc)
        done = max(cast + n * cc, resampler + cc)
        heapq.heappush(casters, done)
        heapq.heappush(buffers, done)
        end = max(end, done)
    total = int(samples.sum())
    return end, total * rc, total * cc
