"""What every transaction model shares: its result, the per-step loads of a plan, and
the frame a model that reads the volume (empty space, block caches, rays' ends) takes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hwsim.arch import ArchConfig
from hwsim.errors import InputError, NotAvailableError
from hwsim.golden.positions import SamplePlan
from hwsim.memory import MemoryConfig
from hwsim.transfer import TransferFunction
from hwsim.volumes.volume import Volume
from models.datapath import Datapath

__all__ = ["ReadsTheFrame", "TxnTiming", "require_pipeline_clock", "slice_loads"]


@dataclass
class TxnTiming:
    """Cycles and counters of one transaction-level frame."""

    cycles: int
    counters: dict[str, Any]


def slice_loads(plan: SamplePlan) -> tuple[np.ndarray, np.ndarray]:
    """Samples taken and rays finishing at each step of ``plan``, from its ray ranges."""
    n = plan.n_steps
    if plan.ray_ids.size == 0:
        return np.zeros(n, np.int64), np.zeros(n, np.int64)
    starts = np.bincount(plan.j_lo, minlength=n + 1)
    stops = np.bincount(plan.j_hi + 1, minlength=n + 1)
    samples = np.cumsum(starts - stops)[:n]
    finishing = np.bincount(plan.j_hi, minlength=n)[:n]
    return samples.astype(np.int64), finishing.astype(np.int64)


def require_pipeline_clock(memory: MemoryConfig, arch: ArchConfig) -> MemoryConfig:
    """``memory``, refused unless its SDRAM runs at the pipeline clock: the transaction
    models count SDRAM commands and pipeline work in one clock (the cycle rung models a
    ``memory.clock_ratio``)."""
    if memory.sdram.clock_ratio != 1.0:
        raise NotAvailableError(
            "the transaction model runs the SDRAM at the pipeline clock",
            source=arch.source,
            key="memory.clock_ratio",
            allowed="1.0",
        )
    return memory


class ReadsTheFrame:
    """Mixin of the transaction models whose timing depends on the frame's data: they need
    the volume and transfer function, and ``run()`` takes the rays' termination steps
    (``stopped``) from the functional image when the caller gives them."""

    READS_THE_FRAME = True

    def _take_frame(
        self,
        arch: ArchConfig,
        volume: Volume | None,
        transfer: TransferFunction | None,
        stopped: np.ndarray | None,
        datapath: Datapath | None,
        why: str,
    ) -> None:
        if volume is None or transfer is None:
            raise InputError(
                f"{arch.name}'s transaction model needs the volume and transfer function ({why})",
                key="volume",
                allowed="transaction_timing(..., volume=, transfer=)",
            )
        self.volume, self.transfer, self.stopped = volume, transfer, stopped
        self.datapath = datapath or Datapath.for_volume(arch, volume)
