"""Driver / monitor of one ready/valid stream pair, shared by the Amaranth-simulator tier
(tests/rtl) and the cocotb tier (tests/cosim), plus payload packing by layout.

A :class:`StreamBench` is stepped once per clock cycle by a simulator adapter:
:meth:`drive` gives the input ``valid``/``payload`` and output ``ready`` for the cycle,
:meth:`observe` records the handshakes seen in it.  Idle gaps (``valid`` low between
transfers) and backpressure (``ready`` low) come from seeded random masks; the stream
rules are checked as the cycles pass: an offered payload stays until accepted, and an
output refused by backpressure must hold its payload.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from amaranth.hdl import Shape
from amaranth.lib import data

__all__ = ["Leaf", "leaves", "pack", "unpack", "StreamBench", "PHASES"]

#: The idle-gap x backpressure crossing: (probability of an idle cycle, of backpressure).
PHASES = ((0.0, 0.0), (0.3, 0.0), (0.0, 0.3), (0.3, 0.3))


@dataclass(frozen=True)
class Leaf:
    """One scalar field of a packed layout: ``key`` (``"acc"``), ``index`` into an array
    field (or None), bit ``offset``, ``width``, ``signed``."""

    key: str
    index: int | None
    offset: int
    width: int
    signed: bool


def leaves(layout) -> list[Leaf]:
    """Scalar fields of a struct of scalars and one-level arrays, first field at bit 0."""
    out = []
    for name, field in data.Layout.cast(layout):
        shape = field.shape
        if isinstance(shape, data.ArrayLayout):
            elem = Shape.cast(shape.elem_shape)
            for k in range(shape.length):
                out.append(Leaf(name, k, field.offset + k * elem.width, elem.width, elem.signed))
        else:
            s = Shape.cast(shape)
            out.append(Leaf(name, None, field.offset, s.width, s.signed))
    return out


def pack(layout, fields: dict[str, np.ndarray]) -> list[int]:
    """Pack ``{key: (n,) or (n, k) int arrays}`` into ``n`` Python-int payload words."""
    total = None
    for leaf in leaves(layout):
        column = np.asarray(fields[leaf.key])
        column = column[:, leaf.index] if leaf.index is not None else column
        mask = (1 << leaf.width) - 1
        part = (column.astype(object) & mask) << leaf.offset
        total = part if total is None else total + part
    return [int(v) for v in total]


def unpack(layout, words: list[int]) -> dict[str, np.ndarray]:
    """Inverse of :func:`pack`: ``{key: int64 array}`` (arrays as ``(n, k)``)."""
    w = np.array(words, dtype=object)
    columns: dict[str, list[np.ndarray]] = {}
    arrays = set()
    for leaf in leaves(layout):
        mask = (1 << leaf.width) - 1
        col = ((w >> leaf.offset) & mask).astype(np.int64) if w.size else np.zeros(0, np.int64)
        if leaf.signed:
            col = np.where(col >= 1 << (leaf.width - 1), col - (1 << leaf.width), col)
        columns.setdefault(leaf.key, []).append(col)
        if leaf.index is not None:
            arrays.add(leaf.key)
    return {k: np.stack(v, axis=1) if k in arrays else v[0] for k, v in columns.items()}


class StreamBench:
    """Driver + monitor of ``words`` through a unit.

    Parameters
    ----------
    words : list of int
        Packed input payloads, in order.
    idle, stall : float
        Probabilities of an idle input cycle (between transfers) and of output
        backpressure in a cycle.
    seed : int
    """

    def __init__(self, words: list[int], idle: float, stall: float, seed: int):
        self.words = words
        rng = np.random.default_rng(seed)
        cap = 4 * len(words) + 64
        self.idle = (rng.random(cap) < idle).tolist()
        self.stall = (rng.random(cap) < stall).tolist()
        self.cycle = 0
        self.next_in = 0
        self.offering = False
        self.ready = True
        self.outputs: list[int] = []
        self.in_cycles: list[int] = []
        self.out_cycles: list[int] = []
        self.held: int | None = None  # payload refused last cycle, must persist
        self.violations: list[str] = []

    @property
    def done(self) -> bool:
        return len(self.outputs) == len(self.words)

    def drive(self) -> tuple[int, int, int]:
        """``(in_valid, in_payload, out_ready)`` for the current cycle."""
        c = self.cycle % len(self.idle)
        if not self.offering and self.next_in < len(self.words) and not self.idle[c]:
            self.offering = True
        self.ready = not self.stall[c]
        word = self.words[self.next_in] if self.offering else 0
        return int(self.offering), word, int(self.ready)

    def observe(self, in_ready: int, out_valid: int, out_payload: int) -> None:
        """Record this cycle's handshakes (values settled before the clock edge)."""
        if self.held is not None and (not out_valid or out_payload != self.held):
            self.violations.append(f"cycle {self.cycle}: refused output changed or dropped")
        self.held = None
        if self.offering and in_ready:
            self.in_cycles.append(self.cycle)
            self.next_in += 1
            self.offering = False
        if out_valid:
            if self.ready:
                self.outputs.append(out_payload)
                self.out_cycles.append(self.cycle)
            else:
                self.held = out_payload
        self.cycle += 1

    def check(self, latency: int, idle: float, stall: float, ii: int = 1) -> None:
        """Stream rules, latency (every transfer when never backpressured) and the
        initiation interval (one input every ``ii`` cycles when neither idle nor
        backpressured)."""
        assert not self.violations, self.violations[:3]
        assert len(self.in_cycles) == len(self.words)
        lat = np.array(self.out_cycles) - np.array(self.in_cycles)
        assert (lat >= latency).all()
        if stall == 0:
            assert (lat == latency).all(), f"latency {sorted(set(lat.tolist()))} != {latency}"
            if idle == 0:
                spacing = set(np.diff(self.in_cycles).tolist())
                assert self.in_cycles[0] == 0 and spacing <= {ii}, f"II {spacing} != {ii}"
