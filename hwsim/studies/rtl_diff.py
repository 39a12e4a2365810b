"""``hwsim rtl diff``: where the RTL top and the cycle rung first part ways on a frame.

# Ref: docs/rtl.md ("The RTL checks the cycle rung"); docs/cycle.md timing rules 1-6.

Both rungs render the same frame; each reports the same three event streams at frame
clocks (0 = the prime period's first clock, frozen clocks counted):

* ``S``: the clock each slice period's first slot issues (rules 1-2);
* ``F``: every clock the core is frozen by a full pixel FIFO (rule 4);
* ``P``: every pixel the bus pops, with its ray (rules 4-6).

The RTL's come from the simulator's testbench (``+events``: the top's ``period_start``,
``frozen`` and ``pixel`` ports at its ``frame_clock``); a pixel delivered at clock ``c``
was popped at ``c - 2`` (the bus's FIFO read and compositing-buffer read stages,
rtl/top.py).  The cycle rung's are its own timing (``Cube4Machine.bus_events``).  The
report names, per stream, the first entry that differs, and the earliest clock of all:
where to look in a ``--trace`` waveform.  Nothing is fed from one rung into the other.

The vg500 top (VolumePro 500, EM-Cube: ``rtl.vg500``) is compared on what both rungs
count: the image, samples, cycles, the clocks the pipelines waited for memory (the RTL's
held clocks, the cycle rung's ``memory.stall_cycles``) and the SDRAM's bursts,
activations and refreshes (the RTL's from the datasheet checkers on the devices' pins,
the cycle rung's from its controller model).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.run.fidelity import (
    algorithms,
    check_scene_fits,
    check_volume_fits,
    check_work,
    resolve_arch,
    value_path_volume,
)
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import Scene
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import load_volume
from hwsim.volumes.volume import Volume

__all__ = ["BUS_READ_CLOCKS", "CounterDiff", "StreamDiff", "RtlDiff", "rtl_diff", "diff_streams"]

#: A pixel popped from the FIFO leaves on the pixel stream this many clocks later.
BUS_READ_CLOCKS = 2
STREAMS = {"S": "period start", "F": "frozen clock", "P": "pixel pop"}


@dataclass
class StreamDiff:
    """One event stream of both rungs: counts and the first entry that differs."""

    name: str
    rtl_count: int
    cycle_count: int
    first_index: int | None = None  # None: identical
    rtl: Any = None
    cycle: Any = None

    @property
    def clock(self) -> int | None:
        """The earliest clock of the first difference (either side's entry)."""
        if self.first_index is None:
            return None
        clocks = [_clock_of(x) for x in (self.rtl, self.cycle) if x is not None]
        return min(clocks) if clocks else None

    def line(self) -> str:
        what = STREAMS[self.name]
        if self.first_index is None:
            return f"{what}s: {self.rtl_count} in both, identical"
        return (
            f"{what} {self.first_index}: rtl {_show(self.rtl)}, cycle rung {_show(self.cycle)} "
            f"({self.rtl_count} vs {self.cycle_count} in all)"
        )


@dataclass
class CounterDiff:
    """One count of both rungs (the vg500 top's comparison)."""

    name: str
    rtl: int
    cycle: int

    @property
    def equal(self) -> bool:
        return self.rtl == self.cycle

    def line(self) -> str:
        if self.equal:
            return f"{self.name}: {self.rtl} in both"
        return f"{self.name}: rtl {self.rtl}, cycle rung {self.cycle} ({self.rtl - self.cycle:+d})"


@dataclass
class RtlDiff:
    """The frame's comparison: cycles of both rungs and each stream's first difference
    (Cube-4 top) or each count's (vg500 top)."""

    rtl_cycles: int
    cycle_cycles: int
    images_equal: bool
    streams: list[StreamDiff] = field(default_factory=list)
    counters: list[CounterDiff] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        same = all(s.first_index is None for s in self.streams)
        same = same and all(c.equal for c in self.counters)
        return same and self.images_equal and self.rtl_cycles == self.cycle_cycles

    @property
    def first_clock(self) -> int | None:
        clocks = [s.clock for s in self.streams if s.clock is not None]
        return min(clocks) if clocks else None

    def lines(self) -> list[str]:
        head = f"cycles: rtl {self.rtl_cycles}, cycle rung {self.cycle_cycles}; images " + (
            "bit-identical" if self.images_equal else "DIFFER"
        )
        out = [head, *(s.line() for s in self.streams), *(c.line() for c in self.counters)]
        if self.identical:
            out.append("no difference")
        elif self.first_clock is not None:
            out.append(f"first difference at frame clock {self.first_clock}")
        return out


def _clock_of(entry) -> int:
    return int(entry[0]) if isinstance(entry, tuple) else int(entry)


def _show(entry) -> str:
    if entry is None:
        return "none"
    if isinstance(entry, tuple):
        return f"clock {entry[0]} (ray {entry[1]})"
    return f"clock {entry}"


def diff_streams(name: str, rtl: list, cycle: list) -> StreamDiff:
    """The first index where two event lists differ (a missing entry differs too)."""
    out = StreamDiff(name, len(rtl), len(cycle))
    for i in range(max(len(rtl), len(cycle))):
        a = rtl[i] if i < len(rtl) else None
        b = cycle[i] if i < len(cycle) else None
        if a != b:
            out.first_index, out.rtl, out.cycle = i, a, b
            break
    return out


def _frame(scene: Scene, arch: str | ArchConfig, volume: Volume | None):
    """The machine frame of ``scene`` on ``arch``, prepared as ``hwsim render`` does."""
    from models.frame import frame_of

    machine = arch if isinstance(arch, ArchConfig) else resolve_arch(arch)
    check_scene_fits(scene, machine)
    if scene.render.gradient is None:
        gradient = algorithms(machine).gradient
        scene = scene.replace(render=dataclasses.replace(scene.render, gradient=gradient))
    if volume is None:
        volume = load_volume(scene.volume, scene.base_dir)
    volume = value_path_volume(scene, volume, machine)
    check_work(scene, volume)
    check_volume_fits(volume, machine)
    transfer = resolve_transfer(scene.transfer, volume, scene.base_dir)
    return frame_of(scene, volume, transfer, machine)


def rtl_diff(
    scene: Scene,
    *,
    arch: str | ArchConfig = "cube4",
    simulator: str = "verilator",
    volume: Volume | None = None,
) -> RtlDiff:
    """Render ``scene`` on ``arch`` at the cycle and rtl rungs and compare their events.

    Raises
    ------
    InputError, NotAvailableError
        What either rung refuses (a machine without an RTL top, a missing simulator).
    """
    from models.backend import Backend
    from models.machines.cube4.cycle import Cube4Machine
    from rtl.frame import RTL_ORDERS, prepare
    from rtl.rung import run_simulator
    from rtl.vg500.frame import is_vg500

    frame = _frame(scene, arch, volume)
    if is_vg500(frame.arch):
        return _vg500_diff(frame, simulator)
    if frame.arch.order not in RTL_ORDERS:
        raise InputError(
            f"{frame.arch.name} has no RTL top",
            key="--arch",
            allowed="the Cube-4 family, volumepro500, em-cube",
        )
    program = prepare(frame)  # the rtl rung's refusals first: no cycle frame wasted
    machine = Cube4Machine(Backend(frame))
    cycle = machine.run()
    rtl, timing = run_simulator(program, simulator, events=True)
    ev, bus = timing["events"], machine.bus_events
    streams = [
        diff_streams("S", ev["S"], [int(c) for c in bus["period_starts"]]),
        diff_streams("F", ev["F"], [int(c) for c in bus["frozen"]]),
        diff_streams(
            "P",
            [(c - BUS_READ_CLOCKS, r) for c, r in ev["P"]],
            [(int(c), int(r)) for c, r in zip(bus["pops"], bus["rays"], strict=True)],
        ),
    ]
    return RtlDiff(
        rtl_cycles=rtl.cycles,
        cycle_cycles=cycle.cycles,
        images_equal=bool(np.array_equal(rtl.image, cycle.image)),
        streams=streams,
    )


#: The vg500 comparison's counts: (name, the rtl rung's counter, the cycle rung's).
VG500_COUNTERS = (
    ("samples", "frame.samples", "frame.samples"),
    ("memory wait clocks", "memory.hold_cycles", "memory.stall_cycles"),
    ("SDRAM bursts", "memory.bursts", "memory.bursts"),
    ("SDRAM activations", "memory.sdram.checker.activates", "memory.sdram.activates"),
    # The frame's (from its start to its last READ); checker.refreshes counts from power-up.
    ("SDRAM refreshes", "memory.sdram.frame_refreshes", "memory.sdram.refreshes"),
)


def _vg500_diff(frame, simulator: str) -> RtlDiff:
    """The vg500 top against the cycle rung: image, cycles and :data:`VG500_COUNTERS`
    (the SDRAM checkers fail the rtl run on any violated datasheet rule)."""
    from models.cycle import render_cycle
    from rtl.vg500.frame import prepare_vg500
    from rtl.vg500.rung import run_vg500

    program = prepare_vg500(frame)  # the rtl rung's refusals first
    cycle = render_cycle(frame)
    rtl, _ = run_vg500(program, simulator)
    rtl.counters.setdefault("frame.samples", rtl.samples)
    counts = {**cycle.counters, "frame.samples": cycle.samples}
    return RtlDiff(
        rtl_cycles=rtl.cycles,
        cycle_cycles=cycle.cycles,
        images_equal=bool(np.array_equal(rtl.image, cycle.image)),
        counters=[
            CounterDiff(name, int(rtl.counters[a]), int(counts[b])) for name, a, b in VG500_COUNTERS
        ],
    )
