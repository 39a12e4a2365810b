"""Energy per frame, per sample, power and area of every published machine on a 256^3 frame,
in its era's node and in a modern one (docs/energy.md's table).

Usage::

    .venv/bin/python benchmarks/energy_table.py [--size 256] [--out benchmarks/results/energy.json]

The CT-like head phantom at ``--size``^3, lit composite (the ``ct`` preset, view 30,15,
image N x N), on each machine: the cycle rung, except VIZARD II's transaction rung (its
cycle model runs ~65 k samples per second; the two rungs' action counts and dynamic
energy are equal, ``tests/energy``).  Each frame's actions are priced in the machine's
``[silicon] technology`` and in ``cmos45`` (:mod:`hwsim.energy`; the same actions, so one
render each).  Power at the published frame rate: energy per frame times the machine's
published ``fps_<size>`` where it has one.  A measurement, not a test: nothing asserted.
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
from hwsim.bench import machine_info
from hwsim.energy import estimate_frame
from hwsim.fidelity import render, resolve_arch
from hwsim.scene import Scene, TransferSpec, ViewSpec
from hwsim.threads import using
from hwsim.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of

__all__ = ["MACHINES", "run", "main"]

#: Machine -> the rung that counts its actions.
MACHINES = {
    "cube4": "cycle",
    "em-cube": "cycle",
    "volumepro500": "cycle",
    "volumepro1000": "cycle",
    "vizard2": "transaction",
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
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "scene": f"head phantom {size}^3, ct preset, lit composite, view 30,15, {size}x{size}",
        "modern_technology": MODERN,
        "cases": cases,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    write_report(run(args.size), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
