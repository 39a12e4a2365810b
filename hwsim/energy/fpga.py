"""Each unit placed and routed on an ECP5: the third measure of area and clock.

# Ref: rtl/fpga.py (Yosys synth_ecp5, nextpnr-ecp5 out of context); docs/energy.md
#      ("Area and clock three ways").

``data/units_fpga.json`` holds every datapath unit (at its default widths) and the Cube-4
top routed on an LFE5U-85F-6, written by ``python -m hwsim.studies.fpga``.  What it shares
with the other two measures: the RTL, nothing else.  The table estimate prices operators
from Horowitz's figures and the ASIC synthesis counts generic Yosys gates priced in
NAND2 equivalents with an inferred delay per gate level; the FPGA figures are LUT4s,
flip-flops, 18x18 multipliers and 16 kbit block RAMs as the vendor-architecture flow
maps them, and ``fmax_mhz`` is nextpnr's static timing of the placed and routed design
(its delays are the ECP5 speed grade's, measured by Lattice, not this project's
technology files).  An ECP5 is 40 nm silicon built for flexibility, so its fmax is not
the ASIC clock the estimate predicts at the machine's node; the comparison shows where the
estimate's depth is wrong (a path the FPGA closes in fewer levels, or a multiplier the
FPGA puts in a DSP), not a calibration.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

__all__ = ["FPGA_BASIS", "fpga_measured", "unit_fpga"]

_DATA = "units_fpga.json"
#: How the FPGA fmax is obtained, to print beside it.
FPGA_BASIS = "routed: nextpnr-ecp5 static timing after place and route (LFE5U-85F, speed 6)"


@cache
def fpga_measured() -> dict[str, Any]:
    """The stored FPGA runs (``data/units_fpga.json``; ``{}`` before the first)."""
    path = resources.files("hwsim.energy") / "data" / _DATA
    if not path.is_file():
        return {}
    return json.loads(path.read_text(encoding="utf-8"))


def unit_fpga(unit: str, clock_hz: float | None = None) -> dict[str, Any] | None:
    """``unit`` as routed on the FPGA: ``fmax_hz``, ``luts``, ``ffs``, ``dsps``,
    ``brams``, ``device`` and, given the machine's ``clock_hz``, whether the routed
    design meets it (None: not measured)."""
    entry = fpga_measured().get("units", {}).get(unit)
    if not entry or entry.get("fmax_mhz") is None:
        return None
    fmax_hz = entry["fmax_mhz"] * 1e6
    return {
        "device": entry["device"],
        "fmax_hz": fmax_hz,
        "luts": entry["luts"],
        "ffs": entry["ffs"],
        "dsps": entry["dsps"],
        "brams": entry["brams"],
        "meets_clock": None if clock_hz is None else fmax_hz >= clock_hz,
        "basis": FPGA_BASIS,
    }
