"""The band between the two energy prices of the same frames: the Horowitz-based tables
(hwsim/energy/technologies) and Accelergy's component library (hwsim/energy/accelergy.py),
per unit, per memory and per frame, for every published machine (docs/energy.md's band
table).

Usage::

    .venv/bin/python benchmarks/energy_band.py [--size 256] [--out FILE.json]

The scene of ``benchmarks/energy_table.py`` (head phantom, ``ct`` preset, lit composite,
view 30,15), each machine's rung there; each frame's actions priced in its era's node and
in ``cmos45``.  ``ratio`` is library / tables.  A measurement, not a test: nothing asserted.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.energy_table import MACHINES, MODERN
from benchmarks.report_io import write_report
from hwsim.core.threads import using
from hwsim.energy.accelergy import band
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.bench import machine_info
from hwsim.volumes import make_phantom
from models.frame import frame_of

__all__ = ["main", "run"]


def run(size: int) -> dict[str, Any]:
    volume = make_phantom("head", size=size)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=size, height=size),
    )
    cases = []
    for name, rung in MACHINES.items():
        arch = resolve_arch(name)
        with using(1):
            done = render(scene, fidelity=rung, arch=arch, volume=volume)
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
        for tech in dict.fromkeys((arch.technology, MODERN)):
            b = band(frame, done.counters, done.elaborated_units, done.cycles, tech)
            cases.append({"arch": name, "rung": rung, **b})
            print(_line(name, tech, b), file=sys.stderr)
    return {
        "schema": 1,
        "benchmark": "energy-band",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "scene": f"head phantom {size}^3, ct preset, lit composite, view 30,15, {size}x{size}",
        "cases": cases,
    }


def _line(name: str, tech: str, b: dict[str, Any]) -> str:
    """One markdown row: each unit's and memory's ratio, then the frame's."""
    units = " ".join(f"{u} {r['ratio']:.3g}" for u, r in b["units"].items())
    mems = " ".join(f"{m} {r['ratio']:.3g}" for m, r in b["memories"].items() if r["ratio"])
    f = b["frame"]
    return (
        f"| {name} | {tech} | {units} | {mems} | {f['horowitz_joules'] * 1e3:.3g} mJ | "
        f"{f['library_joules'] * 1e3:.3g} mJ | {f['ratio']:.3g} | "
        f"{f['not_priced_joules'] * 1e3:.3g} mJ |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    report = run(args.size)
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
