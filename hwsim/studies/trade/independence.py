"""What the two sides of each measured agreement share: its independence, read from the code.

# Ref: issue 30 item 3 (every claimed agreement names its independence).

An agreement between two rungs is evidence only for what the two sides compute apart.
Where both call the same functions for what is compared, equality is a **consistency
check** (a regression test of the plumbing around the shared code), not a measurement of
the error; this module says, per comparison, which it is:

* ``shared``: both sides call the same functions for the quantity compared; its error is
  shown as ``consistency check (shared code: ...)``, never as ``0 (exact)``;
* ``partly shared``: some of what sets the quantity is computed apart, some by the same
  code (named in ``shared``);
* ``independent``: each side computes the quantity on its own (``own`` says what).

The entries were derived by reading the models (``models/machines/*/transaction.py``
against ``models/machines/*/cycle.py`` and what each imports); a change to what a model
imports must update them.  ``benchmarks/transaction_error.py`` writes the verdict beside
every case, ``hwsim trade`` beside every ``cycle_error``; docs/transaction.md has the table.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "SHARED",
    "PARTLY_SHARED",
    "INDEPENDENT",
    "Comparison",
    "TRANSACTION_VS_CYCLE",
    "CYCLE_ESTIMATE_VS_CYCLE",
    "RTL_VS_CYCLE",
    "cycle_comparison",
    "shown_error",
    "transaction_family",
    "transaction_vs_cycle",
]

SHARED, PARTLY_SHARED, INDEPENDENT = "shared", "partly shared", "independent"


@dataclass(frozen=True)
class Comparison:
    """Two sides compared on one quantity, and what they share for it.

    ``shared``: the functions (or constants) both sides call for the compared quantity;
    ``own``: per side, what it computes on its own.
    """

    sides: tuple[str, str]
    quantity: str
    verdict: str
    shared: tuple[str, ...] = ()
    own: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.verdict not in (SHARED, PARTLY_SHARED, INDEPENDENT):
            raise ValueError(f"unknown verdict {self.verdict!r}")
        if self.verdict != INDEPENDENT and not self.shared:
            raise ValueError(f"a {self.verdict} comparison names what is shared")

    @property
    def label(self) -> str:
        """The verdict with what is shared, e.g. ``partly shared (SdramController, ...)``."""
        if self.verdict == INDEPENDENT:
            return INDEPENDENT
        return f"{self.verdict} ({', '.join(_short(s) for s in self.shared)})"

    def as_dict(self) -> dict[str, Any]:
        return {
            "sides": list(self.sides),
            "quantity": self.quantity,
            "independence": self.verdict,
            "shared": list(self.shared),
            "own": dict(self.own),
        }


def _short(name: str) -> str:
    """The name without its module: ``models.machines.cube4.timing.cube4_latency`` ->
    ``cube4_latency``, ``models.backend.Backend.occupied_blocks`` ->
    ``Backend.occupied_blocks``, ``models.units.*.LATENCY`` -> ``units.*.LATENCY``; a
    parenthetical is dropped (:meth:`Comparison.as_dict` keeps it)."""
    dotted = name.partition(" (")[0]
    parts = dotted.split(".")
    keep = 1
    while keep < len(parts) and (
        parts[-keep - 1][:1].isupper() or "*" in (parts[-keep - 1], parts[-keep])
    ):
        keep += 1
    return ".".join(parts[-keep:])


def shown_error(comparison: Comparison, error: float | None, fmt: str = "+.3%") -> str:
    """How an error between the two sides is shown: a consistency check names the shared
    code instead of a number; otherwise the value (``not compared`` when None)."""
    if comparison.verdict == SHARED:
        names = ", ".join(_short(s) for s in comparison.shared)
        return f"consistency check (shared code: {names})"
    if error is None:
        return "not compared"
    return format(error, fmt)


_CYCLE = "cycle rung"
_TXN = "transaction rung"


def _transaction(verdict: str, shared: tuple[str, ...], txn: str, cycle: str) -> Comparison:
    """A transaction-vs-cycle comparison on frame cycles; ``txn`` and ``cycle``: what
    each side computes on its own."""
    return Comparison(
        sides=(_TXN, _CYCLE),
        quantity="frame cycles",
        verdict=verdict,
        shared=shared,
        own={_TXN: txn, _CYCLE: cycle},
    )


#: What VolumePro 500's event model shares with its cycle rung (VolumePro 1000's adds to it).
_VOLUMEPRO_SHARED = (
    "hwsim.memory.SdramController (via SdramTransactionPort)",
    "models.machines.volumepro.memory.layout",
    "models.machines.volumepro.memory.mini_block_bursts",
    "models.machines.volumepro.slab_timing.pipeline_latency",
    "models.machines.volumepro.slab_timing.slab_buffers",
)

#: The transaction rung's event model against the cycle rung, on frame cycles, per family
#: (``volumepro-skipping``: VolumePro 1000's :class:`Vp1000Transaction`; ``vizard2``: VIZARD
#: II's compiled packet model, ``vizard2-shared-loop`` the cycle rung's loop it falls back
#: to, ``vizard2-event-model`` its SimPy packet model).
TRANSACTION_VS_CYCLE: dict[str, Comparison] = {
    "cube4": _transaction(
        SHARED,
        (
            "models.machines.cube4.timing.cube4_latency",
            "models.machines.cube4.timing.cube4_pixel_pushes",
            "hwsim.engine.fifo.freezing_fifo",
            "models.machines.cube4.timing.cube4_lanes",
            "models.machines.cube4.frame.cube4_buffers",
        ),
        txn="the slice period T + slice_cycles + max(0, busiest - T) restated as two "
        "SimPy processes (Cube4Transaction.run); samples per slice from the plan's ray "
        "ranges (slice_loads) and the busiest lane from the compiled walker's positions "
        "(busiest_lanes) -- the same rule and lane function as the cycle rung's",
        cycle="the lanes of the samples it evaluates (HardwareSource positions) and "
        "the period sum in Cube4Machine.frame; latency, pixel pushes and the FIFO are "
        "the shared functions",
    ),
    "volumepro": _transaction(
        PARTLY_SHARED,
        _VOLUMEPRO_SHARED
        + (
            "models.machines.volumepro.fifo_timing.stream_latency",
            "models.machines.volumepro.fifo_timing.uses_slice_fifos",
            "models.machines.volumepro.fifo_timing.DESKEW_WRITE",
        ),
        txn="chunk-granular readiness, freeing and buffer occupancy "
        "(SlabTransaction._schedule, _simulate); on the slice-FIFO machines the periods "
        "of rules 3', 5' restated per chunk from the sample slices' float positions "
        "(fifo_transaction.fifo_schedule); sections (common.sections.bands_of, "
        "band_loads), the pixel bus (common.pixel_bus.PixelBus: rule 8' as a period's "
        "pixels pushed at its start, plus the shared stream latency)",
        cycle="per-mini-block-beam deliveries and the beam-by-beam recurrence "
        "(volumepro.timing.timing_inputs, slab_timing.run_timing) from the data pass's "
        "records: rules 3', 5' per beam from the quantised weights "
        "(fifo_timing.fifo_work), rule 8' per ray (fifo_timing.fifo_end); else the "
        "windows and the pixel FIFO (hwsim.engine.DrainFifo); sections "
        "(SlabMachine._sections)",
    ),
    "volumepro-skipping": _transaction(
        PARTLY_SHARED,
        _VOLUMEPRO_SHARED
        + (
            "models.machines.volumepro.timing.mini_blocks_read",
            "models.backend.Backend.occupied_blocks",
            "hwsim.golden.occupancy.occupancy_from_ranges",
            "models.backend.Backend (the rays' termination steps)",
        ),
        txn="per-beam clock groups and mini-blocks needed from the plan's positions "
        "(vp1000_transaction.beam_skips; compiled, mini_blocks_read's rule written again as "
        "skips_kernel.union_blocks), each slice's busiest lane from them by the "
        "cycle rung's lane rule written again (transaction.sample_lanes, the same rule "
        "as SlabMachine._slots), then the chunk-granular event model as VolumePro 500",
        cycle="live cells from its data pass (SlabMachine._live_cells), then the "
        "beam-by-beam recurrence as VolumePro 500",
    ),
    # VIZARD II's transaction rung times a frame on its compiled packet model
    # (models/machines/vizard2/packet_timing.py, issue 36): the machine's rules written
    # again at packet / round / page-run granularity, its own tag-only cache and SDRAM
    # timing from the arch file's values; it shares the plan (positions, leap ranges),
    # the memory layout's sizes, the latency constants and the rays' termination steps
    # (the functional rung's back end, not the cycle rung's loop).
    "vizard2": _transaction(
        PARTLY_SHARED,
        (
            "hwsim.golden.positions.SamplePlan.position (the plan's positions)",
            "hwsim.golden.positions.SamplePlan.leap",
            "models.backend.Backend.occupied_blocks",
            "models.machines.vizard2.memory.BlockLayout (words and bursts per block)",
            "models.machines.vizard2.config.FEEDBACK",
            "models.machines.vizard2.config.FILL_WRITE",
            "models.machines.vizard2.config.parse_buffers",
            "models.backend.Backend (the rays' termination steps, functional rung)",
        ),
        txn="packets and rounds (ceil(live / P) clocks a round), a tag-only direct-mapped "
        "cache over each sample's cell blocks, fills as page runs timed from the "
        "published SDRAM timings (no command bus, no per-burst controller), refresh, "
        "early termination from the functional rung's steps in its own clocks, the "
        "pixel FIFO in closed form (packet_timing.PacketTiming, packet_timing._frame)",
        cycle="the compiled ray loop with the datapath (RayKernel, ray_memory.gather_round "
        "and fills_timed), BlockCache.fetch, the cycle-exact SdramController, the "
        "opacity that ends a ray from its own blend, hwsim.engine.DrainFifo",
    ),
    # The cycle rung's own ray loop without its datapath (VizardTransaction(frame,
    # shared_loop=True), and the fallback where the packet model refuses a frame): the
    # same code as the cycle rung, so equal cycles are a consistency check.
    "vizard2-shared-loop": _transaction(
        SHARED,
        (
            "models.machines.vizard2.cycle.VizardMachine.timing",
            "models.machines.vizard2.ray_kernel.RayKernel",
            "models.machines.vizard2.ray_memory.gather_round",
            "models.machines.vizard2.ray_memory.fills_timed",
            "hwsim.memory.SdramController",
        ),
        txn="nothing of its own on the loop's frames: the image, colours and shading "
        "skipped; the opacity that ends a ray kept (RayKernel.timing)",
        cycle="the datapath's colours, shading and saturation counts, the image",
    ),
    # The SimPy packet model: VizardTransaction(event_model=True), and frames neither the
    # packet model nor the loop holds; the rules written again over the shared SDRAM.
    "vizard2-event-model": _transaction(
        PARTLY_SHARED,
        (
            "hwsim.memory.SdramController",
            "models.machines.vizard2.memory.BlockLayout.bursts",
            "models.machines.vizard2.config.FEEDBACK",
            "models.machines.vizard2.config.FILL_WRITE",
            "models.machines.vizard2.config.parse_buffers",
            "models.units.interp.interp_taps",
            "models.backend.Backend.occupied_blocks",
            "hwsim.golden.positions.SamplePlan.leap",
            "models.backend.Backend (the rays' termination steps)",
        ),
        txn="the packet issue schedule (SimPy), a tag-only direct-mapped cache "
        "(VizardTransaction._resolve: the same update rule as BlockCache.fetch, written "
        "again), lookups from block-straddle masks (_lookups), early termination's "
        "speculative rounds estimated with unloaded fill times (_last_rounds), the "
        "pixel bus (PixelBus)",
        cycle="round-by-round issue with the real stalls, BlockCache.fetch (tags and "
        "data), the pixel FIFO (hwsim.engine.DrainFifo)",
    ),
}

#: The functional rung's closed-form cycle estimate against the cycle rung.
CYCLE_ESTIMATE_VS_CYCLE = Comparison(
    sides=("functional rung (estimate)", _CYCLE),
    quantity="frame cycles",
    verdict=PARTLY_SHARED,
    shared=("models.units.*.LATENCY",),
    own={
        "functional rung (estimate)": "ceil(samples / P) + slice overhead per step, the "
        "elaborated units' latency once (models.functional.pipeline_latency)",
        _CYCLE: "the machine's timing rules (docs/cycle.md)",
    },
)

#: The Cube-4 RTL top against the cycle rung (images, cycles, frozen clocks).
RTL_VS_CYCLE = Comparison(
    sides=("rtl rung (Cube-4 top)", _CYCLE),
    quantity="image, frame cycles and frozen clocks",
    verdict=PARTLY_SHARED,
    shared=(
        "models.datapath.Datapath (the units' config dataclasses; each unit's LATENCY "
        "is each side's own: the RTL's stage plan, rtl/<unit>.py STAGES, against the "
        "model's constant, compared by the unit tests)",
        "models.machines.cube4.frame.Cube4Frame (slice axes, C, T, buffer capacities)",
        "hwsim.golden.positions.SamplePlan (the per-slice constants are read off the plan)",
        "models.backend.Backend (host tables: LUT, opacity correction, gradient-magnitude "
        "and specular tables; the image's finish and warp)",
        "models.units.skew.cube4_module (and cube4_address_zyx: the host's volume write)",
    ),
    own={
        "rtl rung (Cube-4 top)": "the unit arithmetic and pipeline stages in Amaranth; the "
        "sequencer, beam and "
        "slice FIFOs, ring, gradient look-ahead, pixel FIFO and freeze as registers "
        "(rtl/ may not import models.machines.cube4.timing: import-linter)",
        _CYCLE: "the timing rules of docs/cycle.md (cube4_latency, cube4_pixel_pushes, "
        "freezing_fifo) and the unit arithmetic of models.units",
    },
)


def transaction_family(arch) -> str:
    """The key of :data:`TRANSACTION_VS_CYCLE` for ``arch``: its machine family, and
    ``volumepro-skipping`` for a slab machine that skips beams (the event model
    ``models.machines.volumepro.machine.transaction`` picks for it)."""
    from models.machines import machine_for

    family = machine_for(arch).name
    if family == "volumepro" and (arch.early_termination or arch.space_leaping):
        family = "volumepro-skipping"
    return family


def transaction_vs_cycle(arch) -> Comparison:
    """The transaction-vs-cycle comparison of ``arch``'s family."""
    family = transaction_family(arch)
    if family in TRANSACTION_VS_CYCLE:
        return TRANSACTION_VS_CYCLE[family]
    from models.machines import machine_for

    declared = machine_for(arch).independence  # a family added after this table
    if declared is None:
        raise KeyError(f"family {family!r} declares no transaction-vs-cycle independence")
    return _transaction(
        declared["verdict"], tuple(declared["shared"]), declared["txn"], declared["cycle"]
    )


def cycle_comparison(rung: str, arch) -> Comparison | None:
    """What a rung's ``cycle_error`` against the cycle rung shares with it (None: the
    cycle rung itself, or a rung without cycles)."""
    if rung == "transaction":
        return transaction_vs_cycle(arch)
    if rung == "functional":
        return CYCLE_ESTIMATE_VS_CYCLE
    if rung == "rtl":
        return RTL_VS_CYCLE
    return None
