"""What the slice-order machines of the Cube-4 lineage share (Cube-4 and its descendants,
EM-Cube, VolumePro 500 and 1000): the frame's slice geometry, the one slice direction, the
geometry unit's cells, unit elaboration, the ring hand-off of compositing accumulators,
and the faults of those shared structures.

# Ref: architectures.md sections 1.1-1.3 (slice-by-slice, beam-by-beam order, ring links)
#      and 2-4 (EM-Cube and VolumePro: Cube-4 derived pipelines).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from hwsim.core.errors import InputError
from hwsim.golden.positions import SamplePlan
from models.machines.common.results import elaborate_units
from models.machines.common.slices import SliceDatapath, SlicePath

__all__ = ["SliceFaults", "SliceOrderMachine", "slice_direction", "slice_position"]


@dataclass(frozen=True, kw_only=True)
class SliceFaults:
    """Faults of the structures every slice-order machine has (fault-injection tests).

    ``stuck_module = (k, value)``: memory module ``k`` returns ``value``;
    ``dropped_link = k``: ring link from pipeline ``k + 1`` to ``k`` delivers zeros;
    ``dropped_handoff = k``: accumulators handed to pipeline ``k`` are lost;
    ``beam_fifo_adjust``: entries added to (negative: removed from) the beam delay FIFOs;
    ``pixel_fifo_depth``: the pixel-bus FIFO depth.
    """

    stuck_module: tuple[int, int] | None = None
    dropped_link: int | None = None
    dropped_handoff: int | None = None
    beam_fifo_adjust: int = 0
    pixel_fifo_depth: int | None = None


def slice_direction(plan: SamplePlan) -> bool:
    """True when the slices of ``plan`` are processed in increasing index order.

    A slice-order machine reads slices in one order per frame: a perspective eye between
    the volume's first and last slice along the principal axis is refused.
    """
    if plan.kind == "shear-warp":
        return bool(plan.order[0] <= plan.order[-1])
    signs = np.unique(plan._sign) if plan.ray_ids.size else np.array([1.0])
    if signs.size > 1:
        raise InputError(
            "slices are processed in one order: the eye must not sit between the "
            "volume's first and last slice along the principal axis",
            key="view",
            allowed="a view from outside the volume's slab",
        )
    return bool(signs[0] > 0)


def slice_position(plan: SamplePlan, j: int, forward: bool) -> float:
    """Principal-axis position of sample slice ``j`` of ``plan`` processed in the
    ``forward`` (:func:`slice_direction`) order: the plan's own formula."""
    return plan.principal_position(j, forward)


class SliceOrderMachine:
    """Base of the slice-order cycle machines: set by :meth:`_slice_geometry`, the
    principal axis ``kp``, in-slice axes ``a_ax`` (beams) and ``b_ax`` (along a beam), the
    slice shape, ``C`` clocks per beam and ``T`` per slice for ``P`` pipelines."""

    def _slice_geometry(self, shape: tuple[int, int, int]) -> None:
        self.kp = kp = self.plan.principal_axis
        self.a_ax, self.b_ax = (ax for ax in range(3) if ax != kp)
        self.n_kp, self.n_a, self.n_b = shape[kp], shape[self.a_ax], shape[self.b_ax]
        self.C = -(-self.n_b // self.P)
        self.T = self.n_a * self.C
        self.plane_width = self.n_b + 3  # cells -2 .. n_b
        self.forward = slice_direction(self.plan)

    def _elaborate(self) -> tuple[list[str], list[str]]:
        return elaborate_units(self.be, ("memory", "ring"))

    def _slice_datapath(self) -> SliceDatapath:
        """The ring, beam FIFOs and slice buffers of the ``P`` pipelines, with the links
        ``self.faults`` breaks (set ``faults``, ``counters`` and the geometry first)."""
        path = SlicePath(
            pipelines=self.P,
            beam_fifo_adjust=self.faults.beam_fifo_adjust,
            dropped_link=self.faults.dropped_link,
        )
        return SliceDatapath(path, (self.n_a, self.n_b), self.counters)

    def cell(self, p: np.ndarray, like=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cell index, quantised weight and float fraction of in-slice positions (the
        geometry unit).  ``like``: cells of positions whose fractions are probably the
        same floats; their quantised weights are reused where they are."""
        quantize = self.dp.interp.weight.quantize
        if p.dtype == np.float64 and p.ndim == 1:  # one compiled pass, the GIL released
            c, frac = np.empty(p.size, dtype=np.int64), np.empty(p.size)
            ref = _NO_FRAC if like is None else like[2]
            other = np.empty(p.size, dtype=np.bool_)
            n_other = _cell_rows(p, ref, like is not None, c, frac, other)
        else:
            floor = np.floor(p)
            c, frac = floor, p - floor
            other = frac != (frac[:1] if like is None else like[2])
            n_other = int(other.sum())
        if like is None:
            # Parallel projection: one fraction per slice, usually the very same float
            # for every ray; then quantise it once (same input, same weight).
            if frac.size and not n_other:
                weight = np.full(frac.shape, quantize(frac[:1])[0], dtype=np.int64)
            else:
                weight = quantize(frac)
            return c.astype(np.int64, copy=False), weight, frac
        weight = like[1].copy()
        if n_other:
            weight[other] = quantize(frac[other])
        return c.astype(np.int64, copy=False), weight, frac

    def _hand_off(
        self, rays: np.ndarray, lanes: np.ndarray, prev_lane: np.ndarray, state, counters=None
    ) -> None:
        """Move accumulators to the pipeline of their ray's new sample (ring hand-off),
        counted in ``counters`` (default: the machine's)."""
        counters = self.counters if counters is None else counters
        before = prev_lane[rays]
        moved = (before >= 0) & (before != lanes)
        counters.add("composite.handoffs", int(moved.sum()))
        k = self.faults.dropped_handoff
        if k is not None:
            lost = rays[moved & (lanes == k)]
            if lost.size:
                self.be.cleared_acc(lost, state)
                counters.add("composite.lost_handoffs", int(lost.size))
        prev_lane[rays] = lanes


_NO_FRAC = np.zeros(0)


@numba.njit(cache=True, nogil=True)
def _cell_rows(p, ref, like, c, frac, other):  # pragma: no cover - compiled
    """:meth:`SliceOrderMachine.cell`'s array work in one pass: ``c = floor(p)`` (as
    int64), ``frac = p - floor(p)`` (the same floats as NumPy's) and ``other``, the
    fractions that differ from ``ref[i]`` (``like``) or from the first fraction; returns
    how many do (NaN differs from everything, so it is quantised, and refused, there)."""
    n = 0
    for i in range(p.size):
        f = np.floor(p[i])
        frac[i] = p[i] - f
        c[i] = np.int64(f) if np.isfinite(f) else np.int64(0)
        d = frac[i] != (ref[i] if like else frac[0])
        other[i] = d
        n += d
    return n
