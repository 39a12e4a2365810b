"""Energy per frame, per sample, power and area of every published machine on a 256^3 frame,
in its era's node and in a modern one (docs/energy.md's table).

Usage::

    .venv/bin/python benchmarks/energy_table.py [--size 256] [--out benchmarks/results/energy.json]
    .venv/bin/python benchmarks/energy_table.py --area-two-ways [--out FILE.json]

The CT-like head phantom at ``--size``^3, lit composite (the ``ct`` preset, view 30,15,
image N x N), on each machine: the cycle rung (VIZARD II's too since its compiled ray
loop; its transaction rung's packet model approximates the SDRAM's row activations,
within 2 %, ``tests/energy``).  Each frame's actions are priced in the machine's
``[silicon] technology`` and in ``cmos45`` (:mod:`hwsim.energy`; the same actions, so one
render each).  Power at the published frame rate: energy per frame times the machine's
published ``fps_<size>`` where it has one.  A measurement, not a test: nothing asserted.

``--area-two-ways`` (no render) prints docs/energy.md's "Area two ways" tables instead:
each unit's area from the operator table and from its synthesised RTL
(``hwsim/energy/data/units_synth.json``) at the RTL's widths, in ``cmos45``, with logic and
storage apart (:data:`hwsim.energy.synth.INDEPENDENCE`: only the logic is priced
independently; storage bits are counted on each side and priced by the same SRAM model),
and, with Yosys on PATH, the table's listed operators built by Yosys one by one (the
price ratio and the coverage that split the logic ratio).  The full run's JSON carries
the same rows under ``area_two_ways``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.core.threads import using
from hwsim.energy import estimate_frame, load_technology
from hwsim.energy.model import DATAPATH, rtl_width_inventory, synthesized_unit
from hwsim.energy.synth import INDEPENDENCE, fmax_basis, listed_gate_equivalents
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.bench import machine_info
from hwsim.volumes import make_phantom
from models.frame import frame_of

__all__ = ["MACHINES", "area_two_ways", "run", "main"]

#: Machine -> the rung that counts its actions.
MACHINES = {
    "cube4": "cycle",
    "em-cube": "cycle",
    "volumepro500": "cycle",
    "volumepro1000": "cycle",
    "vizard2": "cycle",
}
MODERN = "cmos45"


def run(size: int) -> dict[str, Any]:
    volume = make_phantom("head", size=size)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=size, height=size),
    )
    cases = []
    for name, rung in MACHINES.items():
        arch = resolve_arch(name)
        start = time.perf_counter()
        with using(1):
            done = render(scene, fidelity=rung, arch=arch, volume=volume)
        wall = time.perf_counter() - start
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
        fps = arch.published.get(f"fps_{size}")
        case: dict[str, Any] = {
            "arch": name,
            "rung": rung,
            "samples": done.samples,
            "cycles": done.cycles,
            "wall_seconds": wall,
            "published_fps": fps,
            "by_technology": {},
        }
        for tech in dict.fromkeys((arch.technology, MODERN)):
            est = done.silicon if tech == arch.technology else estimate_frame(
                frame, done.counters, done.elaborated_units, done.cycles, tech
            )  # fmt: skip
            e, a = est["energy"], est["area"]
            units = sum(u["joules"] for u in e["units"].values())
            case["by_technology"][tech] = {
                "energy_joules": e["total_joules"],
                "units_joules": units,
                "memories_joules": {m: v["joules"] for m, v in e["memories"].items()},
                "static_joules": e["static_joules"],
                "per_sample_joules": e["per_sample_joules"],
                "watts_at_simulated_rate": e["average_watts"],
                "watts_at_published_rate": e["total_joules"] * fps if fps else None,
                "area_mm2": a["total_mm2"],
                "units_area_mm2": sum(u["mm2"] for u in a["units"].values()),
                "area_per_pipeline_mm2": a["per_pipeline_mm2"],
                "buffers_mm2": {b: v["mm2"] for b, v in a["buffers"].items()},
                "units_below_clock": [
                    u
                    for u, v in a["units"].items()
                    if v["synthesized"] and v["synthesized"]["meets_clock"] is False
                ],  # fmt: skip
            }
        cases.append(case)
        era = case["by_technology"][arch.technology]
        print(
            f"{name:<14} {rung:<11} {arch.technology}: {era['energy_joules'] * 1e3:8.2f} mJ "
            f"{era['per_sample_joules'] * 1e9:6.2f} nJ/sample {era['area_mm2']:8.1f} mm^2  "
            f"({wall:.1f} s)",
            file=sys.stderr,
        )
    return {
        "schema": 1,
        "benchmark": "energy-table",
        "area_two_ways": area_two_ways(with_yosys=False),
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "scene": f"head phantom {size}^3, ct preset, lit composite, view 30,15, {size}x{size}",
        "modern_technology": MODERN,
        "cases": cases,
    }


def area_two_ways(with_yosys: bool = True, era: str = "cmos350") -> dict[str, Any]:
    """Each synthesised unit's area two ways at 45 nm (one pipeline, the RTL's default
    widths; VolumePro 500's silicon, whose clock the estimated fmax is held against), logic
    and storage apart; ``with_yosys`` (and Yosys on PATH) adds the listed operators built
    one by one: ``price`` = table logic / their Yosys gates, ``coverage`` = their Yosys
    gates / the unit's RTL logic, so ``logic_ratio = price x coverage``."""
    import shutil

    from hwsim.volumes import make_phantom
    from models.datapath import Datapath
    from models.machines import machine_for

    arch = resolve_arch("volumepro500")
    silicon = machine_for(arch).silicon(
        arch, Datapath.for_volume(arch, make_phantom("ball", size=8))
    )
    tech, old = load_technology(MODERN), load_technology(era)
    yosys = with_yosys and shutil.which("yosys") is not None
    rows = []
    for unit in DATAPATH:
        syn = synthesized_unit(unit, silicon, tech, arch)
        if syn is None:
            continue
        row = {
            "unit": unit,
            "table_logic_mm2": syn["table_logic_mm2"],
            "rtl_logic_mm2": syn["logic_mm2"],
            "rtl_gate_equivalents": syn["gate_equivalents"],
            "rtl_flip_flops": syn["flip_flops"],
            "logic_ratio": syn["logic_table_over_synthesized"],
            "table_storage_bits": syn["table_storage_bits"],
            "rtl_storage_bits": syn["memory_bits"],
            "table_storage_mm2": syn["table_storage_mm2"],
            "rtl_storage_mm2": syn["storage_mm2"],
            "total_ratio": syn["table_over_synthesized"],
            "logic_levels": syn["logic_levels"],
            "fmax_hz": {
                MODERN: syn["fmax_hz"],
                era: 1e12 / (syn["logic_levels"] * old.gate_level_ps),
            },
        }
        if yosys:
            listed = listed_gate_equivalents(rtl_width_inventory(unit, silicon, syn["params"]))
            row["listed_yosys_gate_equivalents"] = listed
            row["price"] = syn["table_logic_mm2"] * 1e6 / tech.gate_um2(listed)
            row["coverage"] = listed / syn["gate_equivalents"]
        rows.append(row)
    return {
        "technology": MODERN,
        "independence": INDEPENDENCE,
        "fmax": fmax_basis(tech),
        "command": "benchmarks/energy_table.py --area-two-ways",
        "units": rows,
    }


def _print_area_two_ways(result: dict[str, Any]) -> None:
    """docs/energy.md's tables, as Markdown."""
    print(f"independence: {result['independence']}\nfmax: {result['fmax']}\n")
    print("| unit | table logic mm^2 | RTL logic mm^2 (GE, flip-flops) | logic table / RTL "
          "| listed ops: table / Yosys | Yosys of listed ops / RTL logic |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for r in result["units"]:
        extra = [f"{r[k]:.2f}" if k in r else "-" for k in ("price", "coverage")]
        print(
            f"| {r['unit']} | {r['table_logic_mm2']:.4f} | {r['rtl_logic_mm2']:.4f} "
            f"({r['rtl_gate_equivalents'] / 1e3:.1f} k, {r['rtl_flip_flops']}) "
            f"| {r['logic_ratio']:.3f} | {extra[0]} | {extra[1]} |"
        )
    print("\n| unit | table storage bits | RTL storage bits | table / RTL bits "
          "| storage mm^2 table / RTL (shared price) | total table / RTL |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for r in result["units"]:
        bits = r["table_storage_bits"] / r["rtl_storage_bits"] if r["rtl_storage_bits"] else None
        print(
            f"| {r['unit']} | {r['table_storage_bits']} | {r['rtl_storage_bits']} "
            f"| {'-' if bits is None else f'{bits:.3f}'} "
            f"| {r['table_storage_mm2']:.4f} / {r['rtl_storage_mm2']:.4f} "
            f"| {r['total_ratio']:.2f} |"
        )
    era = [k for k in result["units"][0]["fmax_hz"] if k != MODERN][0]
    print(f"\n| unit | gate levels | est. fmax {MODERN} | est. fmax {era} |\n|---|---|---|---|")
    for r in result["units"]:
        f = r["fmax_hz"]
        print(
            f"| {r['unit']} | {r['logic_levels']} | {f[MODERN] / 1e6:.0f} MHz "
            f"| {f[era] / 1e6:.1f} MHz |"
        )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--out", type=Path)
    p.add_argument(
        "--area-two-ways",
        action="store_true",
        help="print docs/energy.md's area-two-ways tables (no render)",
    )
    args = p.parse_args(argv)
    if args.area_two_ways:
        result = area_two_ways()
        _print_area_two_ways(result)
        if args.out:
            write_report(result, args.out)
        return 0
    write_report(run(args.size), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
