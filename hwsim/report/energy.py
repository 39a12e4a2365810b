"""The report's energy and area section of one run (``stats.json``'s ``energy``, ``area``
and ``technology``, from :mod:`hwsim.energy`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hwsim.energy.fpga import FPGA_BASIS
from hwsim.energy.synth import INDEPENDENCE
from hwsim.report import plots

__all__ = ["energy_blocks"]


def _g(v: Any, spec: str = ".4g") -> str:
    return "-" if v is None else format(v, spec)


def energy_blocks(stats: dict[str, Any], out: Path, index: int, not_recorded: str) -> list:
    """Blocks: totals, the breakdown plots, and each unit's area two ways and clock."""
    blocks: list = [("h3", "Energy and area")]
    energy, area, tech = stats.get("energy"), stats.get("area"), stats.get("technology")
    if not energy or not area:
        blocks.append(("p", f"Energy and area: {not_recorded} by the {stats['fidelity']} rung."))
        return blocks
    blocks.append(
        (
            "table",
            ["quantity", "value"],
            [
                ["technology", f"{tech['name']} ({tech['node_nm']:g} nm, {tech['vdd']:g} V)"],
                ["energy per frame (J)", _g(energy["total_joules"])],
                ["  dynamic / static (J)", f"{_g(energy['dynamic_joules'])} / "
                 f"{_g(energy['static_joules'])}"],
                ["energy per sample (J)", _g(energy["per_sample_joules"])],
                ["average power at the simulated frame rate (W)", _g(energy["average_watts"])],
                ["area (mm^2)", _g(area["total_mm2"])],
                ["area per pipeline, units (mm^2)", _g(area["per_pipeline_mm2"])],
                ["area (GE: NAND2 gate equivalents)", _g(area["gate_equivalents"], ".3e")],
            ],
        )
    )  # fmt: skip
    for plot, alt in (
        (plots.plot_energy(energy, plots.plot_path(out, "energy", index)), "energy breakdown"),
        (plots.plot_area(area, plots.plot_path(out, "area", index)), "area breakdown"),
    ):
        if plot is not None:
            blocks.append(("img", plot, alt))
    rows, basis, independence = _unit_rows(area)
    if rows:
        blocks.append(
            (
                "p",
                "Each unit's area two ways (one pipeline, the RTL's default widths), logic "
                "and storage apart: the operator table against the synthesised RTL's Yosys "
                "cells in gate equivalents; the storage bits each side counts. "
                f"Independence: {independence or INDEPENDENCE}, so only the logic ratio "
                "tests the table. The clock its longest path allows, against the machine's "
                f"{_g(stats['clock_hz'] / 1e6)} MHz, is an {basis or 'estimate'}. "
                "The third way shares only the RTL with the other two: the same Verilog "
                "placed and routed on an ECP5 FPGA (LUT4s, flip-flops, 18x18 multipliers, "
                f"16 kbit block RAMs; fmax {FPGA_BASIS}), so the routed fmax beside the "
                "estimate shows the estimate's error on a real device (docs/energy.md).",
            )
        )
        header = ["unit", "table logic mm^2", "RTL logic mm^2", "logic table / RTL",
                  "table storage bits", "RTL storage bits", "storage mm^2 (shared price)",
                  "gate levels", "est. fmax MHz", "meets clock (est.)",
                  "FPGA LUT/FF/DSP/BRAM", "routed fmax MHz (ECP5)"]  # fmt: skip
        blocks.append(("table", header, rows))
    other = {u: e["rtl_differs"] for u, e in area["units"].items() if e.get("rtl_differs")}
    if other:
        listed = "; ".join(f"{u} ({why})" for u, why in other.items())
        blocks.append(
            ("p", f"Not compared two ways, the RTL being another kind of unit: {listed}.")
        )
    return blocks


def _unit_rows(area: dict[str, Any]) -> tuple[list, str | None, str | None]:
    """Each synthesised unit's row (table vs RTL area, clock, FPGA), the fmax basis and
    what the two areas share, as the units' entries state them."""
    rows: list = []
    basis = independence = None
    for unit, entry in area["units"].items():
        syn = entry.get("synthesized")
        if syn:
            meets = {True: "yes", False: "NO", None: "-"}[syn["meets_clock"]]
            basis = syn.get("fmax_basis", basis)
            independence = syn.get("independence", independence)
            rows.append(
                [
                    unit,
                    _g(syn.get("table_logic_mm2")),
                    _g(syn.get("logic_mm2")),
                    _g(syn.get("logic_table_over_synthesized"), ".2f"),
                    _g(syn.get("table_storage_bits"), "d"),
                    _g(syn["memory_bits"], "d"),
                    _g(syn.get("storage_mm2")),
                    str(syn["logic_levels"]),
                    _g(syn["fmax_hz"] / 1e6 if syn["fmax_hz"] else None, ".0f"),
                    meets,
                    *_fpga_cells(entry.get("fpga")),
                ]
            )
    return rows, basis, independence


def _fpga_cells(fpga: dict[str, Any] | None) -> list[str]:
    """The FPGA columns of a unit: its resources and routed fmax (``-``: not routed)."""
    if not fpga:
        return ["-", "-"]
    counts = "/".join(str(fpga[k]) for k in ("luts", "ffs", "dsps", "brams"))
    return [counts, _g(fpga["fmax_hz"] / 1e6, ".0f")]
