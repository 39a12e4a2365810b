"""Area and clock from the units' synthesised RTL: the second opinion on the table's area.

# Ref: rtl/build.py (the generic Yosys flow: techmap gates, ``stat``, ``ltp -noff``);
#      docs/energy.md ("Area two ways", "Does each unit meet its clock?").

``data/units_synth.json`` holds each datapath unit's RTL synthesised at its default
widths (cells by type, flip-flops, SRAM bits, the longest path between flip-flops in
gates), written by ``python -m hwsim.energy.synth`` (which runs ``hwsim rtl build all``;
the ``synth`` tests re-synthesise a unit and compare).  From it:

* **logic**: each generic gate and flip-flop in NAND2 equivalents of a standard-cell
  library (:data:`GATE_EQUIVALENTS`, NanGate 45 nm X1 cells [R]).  This is the
  independent side of "area two ways": the table prices operators from Horowitz's
  figures, this counts the cells Yosys builds;
* **storage**: the RTL's memories, counted in bits (their own count, from the Verilog)
  but priced per bit by the SAME :meth:`Technology.storage_um2` the table uses: where
  SRAM dominates a unit, the two areas agree through that shared price, not
  independently (:data:`INDEPENDENCE`);
* **fmax** (an estimate, :func:`fmax_basis`): the longest path's gate count times an
  inferred delay per generic gate level (1.5 FO4), not a timing analysis (no cell
  library timing, no wires, no sizing).  The unit's pipeline already holds its
  ``LATENCY`` registers.  Yosys' techmap builds Brent-Kung adders and carry-save
  multipliers but never restructures or retimes the unrolled square root and dividers,
  so the depth is the RTL as written, not what a timing-driven flow would reach.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any

from hwsim.core.paths import write_text_atomic
from hwsim.energy.technology import FF_GATE_EQUIVALENTS, Technology

__all__ = [
    "GATE_EQUIVALENTS",
    "INDEPENDENCE",
    "fmax_basis",
    "gate_equivalents",
    "operator_gate_equivalents",
    "synthesised",
    "unit_silicon",
]

#: NAND2 equivalents of Yosys' generic cells: NanGate 45 nm open cell library X1 cells
#: over NAND2_X1's 0.798 um^2 [R] (INV 0.532, AND2/OR2 1.064, XOR2 1.596, MUX2 1.862,
#: DFF 4.522); a flip-flop with enable and synchronous reset adds a MUX2 and an AND2.
GATE_EQUIVALENTS = {
    "$_NOT_": 0.67,
    "$_AND_": 1.33,
    "$_OR_": 1.33,
    "$_NAND_": 1.0,
    "$_NOR_": 1.0,
    "$_XOR_": 2.0,
    "$_XNOR_": 2.0,
    "$_ANDNOT_": 1.33,
    "$_ORNOT_": 1.33,
    "$_MUX_": 2.33,
}
_DATA = "units_synth.json"
#: What "area two ways" compares independently, and what it shares (docs/energy.md).
INDEPENDENCE = (
    "logic: independent (operator table from the unit models vs Yosys cells of the RTL); "
    "storage: bits counted independently, priced by the same SRAM model (shared)"
)


def fmax_basis(tech: Technology) -> str:
    """How a unit's fmax is obtained, to print beside it: an estimate, not timing."""
    fo4 = tech.v("timing", "gate_level_fo4")
    return f"estimate: logic levels x {fo4:g} FO4 (inferred unit delay), not timing analysis"


@cache
def synthesised() -> dict[str, Any]:
    """The stored synthesis of every unit (``data/units_synth.json``)."""
    text = (resources.files("hwsim.energy") / "data" / _DATA).read_text(encoding="utf-8")
    return json.loads(text)


def gate_equivalents(cells_by_type: dict[str, int]) -> float:
    """Logic and flip-flops of a synthesised unit in NAND2 equivalents (memories apart)."""
    total = 0.0
    for cell, n in cells_by_type.items():
        if cell.startswith("$mem"):
            continue
        if "DFF" in cell:
            extra = ("E" in cell.split("DFF")[1]) * 2.33 + cell.startswith("$_SDFF") * 1.33
            total += n * (FF_GATE_EQUIVALENTS + extra)
        elif cell in GATE_EQUIVALENTS:
            total += n * GATE_EQUIVALENTS[cell]
        else:
            raise KeyError(f"no gate equivalent for Yosys cell {cell}")
    return total


def unit_silicon(unit: str, tech: Technology, clock_hz: float) -> dict[str, Any] | None:
    """One pipeline's ``unit`` as synthesised: its area in ``tech``, its longest path and
    the clock it meets (None: no RTL of that unit)."""
    entry = synthesised()["units"].get(unit)
    if entry is None:
        return None
    ge = gate_equivalents(entry["cells_by_type"])
    logic_um2 = tech.gate_um2(ge)
    storage_um2 = tech.storage_um2(entry["memory_bits"])  # the table's price per bit
    levels = entry["logic_levels"]
    fmax = 1e12 / (levels * tech.gate_level_ps) if levels else None
    return {
        "mm2": (logic_um2 + storage_um2) / 1e6,
        "logic_mm2": logic_um2 / 1e6,
        "storage_mm2": storage_um2 / 1e6,
        "gate_equivalents": ge,
        "flip_flops": entry["flip_flops"],
        "memory_bits": entry["memory_bits"],
        "logic_levels": levels,
        "latency": entry["latency"],
        "fmax_hz": fmax,
        "fmax_basis": fmax_basis(tech),
        "meets_clock": None if fmax is None else fmax >= clock_hz,
        "params": entry["params"],
    }


@cache
def operator_gate_equivalents(kind: str, a: int, b: int = 0) -> float:
    """One operator of the table's inventory built alone and synthesised by the same Yosys
    flow as the units (:func:`rtl.build.synthesize`), in NAND2 equivalents: ``add`` of two
    ``a``-bit operands, ``mult`` ``a`` x ``b`` bits, ``register`` ``a`` flip-flops loaded
    under an enable with a synchronous reset (as :class:`rtl.common.StallingPipeline`
    builds them).  Needs a full Yosys on PATH.  What the table's operator price is
    measured against (docs/energy.md, "Area two ways")."""
    from amaranth import Module
    from amaranth.lib import wiring
    from amaranth.lib.wiring import In, Out

    from rtl.build import synthesize
    from rtl.export import to_verilog

    ports = {
        "add": {"x": In(a), "y": In(a), "o": Out(a + 1)},
        "mult": {"x": In(a), "y": In(b), "o": Out(a + b)},
        "register": {"x": In(a), "en": In(1), "o": Out(a)},
    }

    class _Operator(wiring.Component):
        def elaborate(self, platform):
            m = Module()
            if kind == "add":
                m.d.comb += self.o.eq(self.x + self.y)
            elif kind == "mult":
                m.d.comb += self.o.eq(self.x * self.y)
            else:
                with m.If(self.en):
                    m.d.sync += self.o.eq(self.x)
            return m

    if kind not in ports:
        raise KeyError(f"no operator {kind!r} (add, mult, register)")
    stat = synthesize(to_verilog(_Operator(ports[kind]), "op"), "op")
    return gate_equivalents(stat["cells_by_type"])


def unit_datapath(unit: str, params: dict[str, Any]):
    """The default datapath with ``unit``'s config set to the synthesised ``params`` (the
    widths the table prices when it is compared with the RTL)."""
    from models.datapath import UNIT_CONFIGS, Datapath

    dp = Datapath()
    if unit in UNIT_CONFIGS:
        cfg = getattr(dp, unit)
        names = {f.name for f in dataclasses.fields(cfg)}
        dp = dataclasses.replace(
            dp,
            **{unit: dataclasses.replace(cfg, **{k: v for k, v in params.items() if k in names})},
        )
    if "voxel_bits" in params:
        dp = dataclasses.replace(dp, voxel_bits=params["voxel_bits"])
    return dp


def refresh(path: Path) -> dict[str, Any]:
    """Synthesise every unit (``hwsim rtl build all``) and write the data file."""
    import subprocess
    import tempfile

    from rtl.build import UNITS, build

    with tempfile.TemporaryDirectory(prefix="hwsim-units-") as tmp:
        report = build(list(UNITS), Path(tmp), {})
    version = subprocess.run(["yosys", "-V"], capture_output=True, text=True, check=True)
    keep = ("params", "latency", "ii", "cells", "flip_flops", "cells_by_type", "memories")
    out = {
        "schema": 1,
        "what": "the datapath units' RTL synthesised at their default widths (hwsim.energy.synth)",
        "command": "python -m hwsim.energy.synth  (runs hwsim rtl build all)",
        "yosys": version.stdout.strip(),
        "date": time.strftime("%Y-%m-%d"),
        "flow": report["flow"],
        "units": {
            u: {k: e[k] for k in (*keep, "memory_bits", "logic_levels")}
            for u, e in report["units"].items()
        },
    }
    write_text_atomic(path, json.dumps(out, indent=1, sort_keys=True) + "\n")
    return out


if __name__ == "__main__":
    target = Path(str(resources.files("hwsim.energy") / "data" / _DATA))
    refresh(target)
    print(f"wrote {target}", file=sys.stderr)


def listed_gate_equivalents(inventory) -> float:
    """The logic an operator inventory lists (its operators and pipeline registers; tables
    apart), each operator built alone through the units' Yosys flow
    (:func:`operator_gate_equivalents`): the table's own list at Yosys' gate counts.  Set
    against a unit's synthesised logic it measures how much of the RTL the list covers."""
    total = 0.0
    for op in inventory:
        if op.kind == "register":
            total += operator_gate_equivalents("register", int(op.a * op.instances))
        elif op.kind != "table":
            total += operator_gate_equivalents(op.kind, op.a, op.b) * op.instances
    return total
