"""Area and clock from the units' synthesised RTL: the second opinion on the table's area.

# Ref: rtl/build.py (the generic Yosys flow: techmap gates, ``stat``, ``ltp -noff``);
#      docs/energy.md ("Area two ways", "Does each unit meet its clock?").

``data/units_synth.json`` holds each datapath unit's RTL synthesised at its default
widths (cells by type, flip-flops, SRAM bits, the longest path between flip-flops in
gates), written by ``python -m hwsim.energy.synth`` (which runs ``hwsim rtl build all``;
the ``synth`` tests re-synthesise a unit and compare).  From it:

* **gate equivalents**: each generic gate in NAND2 equivalents of a standard-cell
  library (:data:`GATE_EQUIVALENTS`, NanGate 45 nm X1 cells [R]); SRAMs kept as memories
  priced per bit as the table does;
* **fmax**: the longest path's gates times the technology's delay per gate level; the
  unit's pipeline already holds its ``LATENCY`` registers, so this is the clock the unit
  as built can run at.  Yosys' techmap builds ripple-carry adders and never retimes, so
  the depth is an upper bound of what a timing-driven flow would reach.
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

from hwsim.energy.technology import FF_GATE_EQUIVALENTS, Technology

__all__ = ["GATE_EQUIVALENTS", "gate_equivalents", "synthesised", "unit_silicon"]

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
    um2 = tech.gate_um2(ge) + tech.storage_um2(entry["memory_bits"])
    levels = entry["logic_levels"]
    fmax = 1e12 / (levels * tech.gate_level_ps) if levels else None
    return {
        "mm2": um2 / 1e6,
        "gate_equivalents": ge,
        "memory_bits": entry["memory_bits"],
        "logic_levels": levels,
        "latency": entry["latency"],
        "fmax_hz": fmax,
        "meets_clock": None if fmax is None else fmax >= clock_hz,
        "params": entry["params"],
    }


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
    path.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    return out


if __name__ == "__main__":
    target = Path(str(resources.files("hwsim.energy") / "data" / _DATA))
    refresh(target)
    print(f"wrote {target}", file=sys.stderr)
