"""The VolumePro family's memory timing compared between the cycle and transaction rungs.

Frame cycles within the 2 % contract cannot see the SDRAM's timing: the pipelines wait on
the memory mainly at the first fill, so one clock of ``t_rcd`` moves a 10 152-clock
frame by 9 clocks (docs/evidence.md).  These checks compare instead what the SDRAM
timing decides in both rungs, each with a tolerance argued from what the event model
does differently (docs/transaction.md, "The memory timing, compared"):

* **the SDRAM's counters** (``memory.sdram.*``).  Both rungs time their bursts with the
  one :class:`hwsim.memory.SdramController` (the transaction rung through
  ``SdramTransactionPort``), so equal counters are a **consistency check** of what each
  rung hands that controller: its burst stream (read order and skip map: each rung's
  own; module, bank and row: the shared mini-block layout), its arrival cycles (each
  rung's own input buffer) and its device parameters (each rung parses ``[memory]`` and
  builds its own controllers).  A mutation of the transaction rung's parameters is a
  change to one of those inputs; an error inside the controller is in both rungs and
  cannot show here (``tests/memory`` holds it to an independent checker and event form).
* **the pipelines' memory stall** (``memory.stall_cycles``), computed apart: the event
  model's SimPy waits on chunk readiness against the cycle rung's beam-by-beam
  recurrence, over delivery cycles from the shared controller.  Compared with the event
  model at its finest granularity (:data:`FINEST_GROUPS`: one mini-block beam per chunk,
  a group of the two beams ``2u, 2u + 1`` that need the same last mini-block beam), where
  the documented granularity error (a whole chunk at the first fill) is zero.

Tolerances, by regime (read off the cycle rung's counters, the reference):

``unthrottled``
    the input buffer holds every mini-block beam the frame reads
    (``memory.mbb_reads <= memory.slab_buffer_mbbs``): both rungs queue every burst at
    cycle 0, so the controller sees the same requests at the same cycles: every SDRAM
    counter equal, the stall equal.
``backlogged``
    the buffer throttles the reads, but the SDRAM never waited for a request
    (``memory.sdram.stall_arrival_cycles == 0``): a freed slot is an arrival cycle the
    controller is already past, in the cycle rung when the last beam needing a
    mini-block beam ends and in the event model when its pair ends (one beam later), so
    the schedule is still the backlogged stream's: everything equal as above.  (Were the
    backlog at a freed slot ever under one beam, the event model's own
    ``stall_arrival_cycles`` would turn positive and the check fail naming it: the
    freeing granularity, not the SDRAM timing.  Not seen on any frame measured.)
``waiting``
    the SDRAM waited for requests (the buffer, freed one beam later in the event model,
    sets the arrival cycles): only what does not depend on them is compared: bursts and
    data-bus cycles (the stream), the first data beats (every module's first burst is
    queued at cycle 0, the buffer empty), refreshes within one per module (the interval,
    976 clocks, is far longer than the one beam by which a last arrival can move).

The stall's tolerance is the difference in the pipelines' own clocks between the rungs
(slice stretch, pixel-FIFO stalls), one for one (0 wherever they agree: every frame
measured, magnified perspective included since the event model counts each slice's
busiest lane by the cycle rung's lane rule, ``sample_lanes``);
sectioned frames (``section.count > 1``) compare the SDRAM counters only: the bands are
each rung's own (the cycle rung stretches a band's slices by its busiest lane, the
event model does not) and a band starting on an odd row splits a group's mini-block
beams.

Use: ``memory_timing_mismatches(cycle_counters, transaction_counters)`` is empty when
the rungs agree; ``transaction_counters`` from ``transaction_timing(frame,
groups=FINEST_GROUPS)`` (the SDRAM counters are compared at any granularity, the stall
at the finest only).  :func:`memory_timing_counters` keeps the counters the checks read
(JSON-serialisable), for a caller that runs each rung in a process of its own.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = [
    "FINEST_GROUPS",
    "SCHEDULE",
    "STREAM",
    "MemoryCheck",
    "assert_memory_timing_agrees",
    "memory_regime",
    "memory_timing_checks",
    "memory_timing_counters",
    "memory_timing_mismatches",
]

#: ``groups=`` for the transaction rung: more beam groups than any slice has mini-block
#: beams, so each chunk is one mini-block beam and each group its two beams.
FINEST_GROUPS = 1 << 20

SDRAM = "memory.sdram."
#: What the burst stream alone sets: exact in every regime.
STREAM = ("bursts", "data_busy_cycles", "first_access_cycles")
#: What the controller's schedule sets from the stream's arrival cycles too.
SCHEDULE = (
    "row_hits",
    "row_misses",
    "row_conflicts",
    "activates",
    "precharges",
    "refreshes",
    "refresh_cycles",
    "stall_bank_cycles",
    "stall_refresh_cycles",
    "stall_arrival_cycles",
    "idle_cycles",
    "elapsed_cycles",
)
_MODULE = re.compile(r"memory\.module\[(\d+)\]\.bursts")
_KEEP = (
    "memory.stall_cycles",
    "memory.mbb_reads",
    "memory.slab_buffer_mbbs",
    "section.count",
    "pipeline.slice_stretch_cycles",
    "pipelines.stretch_cycles",
    "pipelines.stall_cycles",
    "pixel_bus.stall_cycles",
    "transaction.granularity",
)


@dataclass(frozen=True)
class MemoryCheck:
    """One quantity of both rungs: ``transaction - cycle`` must lie in ``[low, high]``;
    ``compared`` False: listed, not held to anything (``why`` says why)."""

    quantity: str
    cycle: int
    transaction: int
    low: int
    high: int
    why: str
    compared: bool = True

    @property
    def difference(self) -> int:
        return self.transaction - self.cycle

    @property
    def ok(self) -> bool:
        return not self.compared or self.low <= self.difference <= self.high

    def __str__(self) -> str:
        bound = f"[{self.low:+d}, {self.high:+d}]" if self.compared else "not compared"
        return (
            f"{self.quantity}: cycle {self.cycle}, transaction {self.transaction} "
            f"({self.difference:+d}; allowed {bound}: {self.why})"
        )


def memory_timing_counters(counters: Mapping[str, Any]) -> dict[str, Any]:
    """The counters :func:`memory_timing_checks` reads, as plain ints and strings."""
    keep = {}
    for key, value in counters.items():
        if key.startswith(SDRAM) or key in _KEEP or _MODULE.fullmatch(key):
            keep[key] = value if isinstance(value, str) else int(value)
    return keep


def memory_regime(cycle: Mapping[str, Any]) -> str:
    """``unthrottled``, ``backlogged`` or ``waiting`` (module docstring), from the cycle
    rung's counters."""
    if cycle["memory.mbb_reads"] <= cycle["memory.slab_buffer_mbbs"]:
        return "unthrottled"
    if cycle[SDRAM + "stall_arrival_cycles"] == 0:
        return "backlogged"
    return "waiting"


def _mbbs_per_chunk(transaction: Mapping[str, Any]) -> int:
    """The event model's chunk size, from ``transaction.granularity`` (``"U mbbs / 2U
    beams"``)."""
    return int(str(transaction["transaction.granularity"]).split()[0])


def _pipeline_clocks(cycle: Mapping[str, Any], transaction: Mapping[str, Any]) -> int:
    """How far the pipelines' own clocks differ between the rungs: slice stretch and
    pixel-FIFO stalls (the event model counts the latter inside ``pipelines.stall_cycles``)."""
    stretch = cycle["pipeline.slice_stretch_cycles"] - transaction["pipelines.stretch_cycles"]
    pixel_t = transaction["pipelines.stall_cycles"] - transaction["memory.stall_cycles"]
    return abs(stretch) + abs(cycle["pixel_bus.stall_cycles"] - pixel_t)


def memory_timing_checks(
    cycle: Mapping[str, Any], transaction: Mapping[str, Any]
) -> list[MemoryCheck]:
    """Every quantity compared between the rungs, with its tolerance and why.

    Parameters
    ----------
    cycle : mapping
        The cycle rung's counters (``render_cycle(frame).counters``).
    transaction : mapping
        The transaction rung's counters on the same frame, from
        ``transaction_timing(frame, groups=FINEST_GROUPS)`` for the stall to be compared.
    """
    regime = memory_regime(cycle)
    modules = sum(1 for key in cycle if _MODULE.fullmatch(key))
    checks = []
    for name in STREAM:
        key = SDRAM + name
        why = "the burst stream; every module's first burst queued at cycle 0"
        checks.append(MemoryCheck(key, cycle[key], transaction[key], 0, 0, why))
    for name in SCHEDULE:
        key = SDRAM + name
        if regime != "waiting":
            why = f"{regime}: the same requests at the same cycles, one controller"
            checks.append(MemoryCheck(key, cycle[key], transaction[key], 0, 0, why))
        elif name == "refreshes":
            why = "waiting: the last request moves by at most a beam, << t_refi"
            checks.append(MemoryCheck(key, cycle[key], transaction[key], -modules, modules, why))
        else:
            why = "waiting: set by arrival cycles each rung's buffer frees"
            checks.append(MemoryCheck(key, cycle[key], transaction[key], 0, 0, why, compared=False))
    key = "memory.stall_cycles"
    if _mbbs_per_chunk(transaction) != 1:
        why = "the event model coarser than one mini-block beam per chunk"
        skip = True
    elif cycle["section.count"] > 1:
        why = "sections: each rung's own bands"
        skip = True
    elif regime == "waiting":
        why = "waiting: delivery cycles set by each rung's buffer"
        skip = True
    else:
        slack = _pipeline_clocks(cycle, transaction)
        why = f"{regime}: equal deliveries, equal waits; pipelines' own clocks differ by {slack}"
        checks.append(MemoryCheck(key, cycle[key], transaction[key], -slack, slack, why))
        skip = False
    if skip:
        checks.append(MemoryCheck(key, cycle[key], transaction[key], 0, 0, why, compared=False))
    return checks


def memory_timing_mismatches(
    cycle: Mapping[str, Any], transaction: Mapping[str, Any]
) -> list[MemoryCheck]:
    """The checks of :func:`memory_timing_checks` that fail (empty: the rungs agree)."""
    return [check for check in memory_timing_checks(cycle, transaction) if not check.ok]


def assert_memory_timing_agrees(
    cycle: Mapping[str, Any], transaction: Mapping[str, Any], *, stall: bool = True
) -> list[MemoryCheck]:
    """Raise AssertionError naming every failing check; ``stall``: the stall must have
    been compared (the transaction at :data:`FINEST_GROUPS`, unsectioned, not waiting).
    Returns the checks."""
    checks = memory_timing_checks(cycle, transaction)
    bad = [check for check in checks if not check.ok]
    assert not bad, "memory timing differs between the rungs:\n" + "\n".join(map(str, bad))
    if stall:
        compared = {check.quantity for check in checks if check.compared}
        assert "memory.stall_cycles" in compared, [str(c) for c in checks if not c.compared]
    return checks
