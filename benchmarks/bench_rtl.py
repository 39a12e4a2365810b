"""Cycle rung against the rtl rung on the same frame: samples per wall second of both.

Usage::

    .venv/bin/python benchmarks/bench_rtl.py [--sizes 8 12 16] [--simulators verilator icarus]
                                             [--repeats 3] [--out FILE.json]

For each size the CT-like head phantom is rendered (lit composite: the default light and
Phong material, ``ct`` preset, view 30,15, image N x N) on ``cube4`` by the cycle rung and by the
rtl rung on each simulator, median of ``--repeats`` after a warm-up (which also makes
the cached simulator build), images and cycle counts checked equal.  Reported per case:
wall seconds and samples per wall second of both rungs and their ratio (goal: the cycle
rung >= 30x the rtl rung), the rtl frame split into host preparation and simulator run,
and the clocks the simulator ran (table loads plus the frame) per wall second.  Nothing
is asserted: benchmarks are not tests.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import median_seconds, write_report
from hwsim.bench import machine_info
from hwsim.fidelity import resolve_arch
from hwsim.golden import make_plan
from hwsim.scene import RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from rtl.frame import prepare
from rtl.rung import run_simulator

__all__ = ["run", "main", "GOAL_RATIO"]

GOAL_RATIO = 30.0


def _case(n: int):
    arch = resolve_arch("cube4")
    volume = make_phantom("head", size=n)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=n, height=n, zoom=1.3),
        render=RenderSpec(mode="composite"),  # lit: gradients and Phong in every pipeline
    )
    tf = resolve_transfer(scene.transfer, volume)
    return arch, volume, scene, tf, make_plan(scene, volume, arch.order)


def _rtl_frame(simulator, arch, volume, scene, tf, plan):
    t0 = time.perf_counter()
    program = prepare(frame_of(scene, volume, tf, arch, plan))
    t1 = time.perf_counter()
    result, timing = run_simulator(program, simulator)
    return result, {"prepare_seconds": t1 - t0, **timing}


def run(sizes: Sequence[int], simulators: Sequence[str], repeats: int) -> dict[str, Any]:
    """Measure every (size, simulator); returns the JSON-ready report."""
    cases = []
    for n in sizes:
        arch, volume, scene, tf, plan = _case(n)
        cycle_s, cyc = median_seconds(
            repeats, render_cycle, frame_of(scene, volume, tf, arch, plan)
        )
        for sim in simulators:
            rtl_s, (res, timing) = median_seconds(
                repeats, _rtl_frame, sim, arch, volume, scene, tf, plan
            )
            case = {
                "size": n,
                "simulator": sim,
                "samples": res.samples,
                "cycles": res.cycles,
                "identical": bool(
                    np.array_equal(res.image, cyc.image) and res.cycles == cyc.cycles
                ),
                "cycle_seconds": cycle_s,
                "rtl_seconds": rtl_s,
                "cycle_samples_per_second": cyc.samples / cycle_s,
                "rtl_samples_per_second": res.samples / rtl_s,
                "ratio": rtl_s / cycle_s,
                "goal_ratio": GOAL_RATIO,
                "rtl_last_frame": timing,
                "rtl_simulated_clocks_per_second": timing["clocks"] / timing["run_seconds"],
            }
            cases.append(case)
            print(
                f"{n:>3}^3 {sim:<9} cycle {case['cycle_samples_per_second'] / 1e3:8.1f} k/s  "
                f"rtl {case['rtl_samples_per_second']:8.0f} /s  ratio {case['ratio']:7.0f}x  "
                f"identical {case['identical']}",
                file=sys.stderr,
            )
    return {
        "schema": 1,
        "benchmark": "cycle-vs-rtl",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "scene": "head phantom, ct preset, lit composite, view 30,15, image N x N, cube4",
        "repeats": repeats,
        "cases": cases,
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[8, 12, 16])
    p.add_argument("--simulators", nargs="+", default=["verilator", "icarus"])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    write_report(run(args.sizes, args.simulators, args.repeats), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
