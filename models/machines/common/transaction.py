"""What every transaction model shares: its result, the per-step loads of a plan, and
the frame a model that reads the volume (empty space, block caches, rays' ends) takes."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hwsim.core.errors import NotAvailableError
from hwsim.golden.positions import SamplePlan
from hwsim.memory import MemoryConfig
from hwsim.spec.arch import ArchConfig
from models.frame import Frame

__all__ = [
    "ReadsTheFrame",
    "TxnTiming",
    "report_progress",
    "require_pipeline_clock",
    "slice_loads",
]


@dataclass
class TxnTiming:
    """Cycles and counters of one transaction-level frame."""

    cycles: int
    counters: dict[str, Any]


def report_progress(model: Any, done: int, total: int) -> None:
    """Tell ``model.progress`` (``progress(done, total)``, set by the caller; None or
    unset: nobody listens) that the event model has simulated ``done`` of its ``total``
    work items (slices, beam groups, ray packets)."""
    progress = getattr(model, "progress", None)
    if progress is not None:
        progress(done, total)


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
    """Mixin of the transaction models whose timing depends on the frame's data (empty
    space, block caches, the rays' ends): ``run()`` takes the rays' termination steps
    from ``stopped`` when the caller sets it, else from the functional rung."""

    READS_THE_FRAME = True
    #: :attr:`models.functional.FunctionalResult.stopped` of the frame, when known.
    stopped: np.ndarray | None = None
    #: How to find them when asked and not known (default: the functional rung; timing
    #: only: an unlit pass, :func:`models.transaction.termination_pass`).
    ends: Callable[[Frame], Any] | None = None

    def termination_steps(self, frame: Frame) -> np.ndarray | None:
        """``stopped``, or the termination steps of ``frame`` found by ``ends`` (asked
        only by a model whose rays may stop: early termination, iso hits)."""
        if self.stopped is not None:
            return self.stopped
        if self.ends is not None:
            return self.ends(frame).stopped
        from models.functional import render_functional  # the image rung, run only here

        return render_functional(frame).stopped
