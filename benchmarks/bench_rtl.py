"""Cycle rung against the rtl rung on the same frame, and the rtl rung's own speed.

Usage::

    .venv/bin/python benchmarks/bench_rtl.py [--sizes 16 64 128] [--simulators verilator icarus]
                                             [--icarus-max 16] [--repeats 3] [--out FILE.json]

For each size the CT-like head phantom is rendered (lit composite: the default light and
Phong material, ``ct`` preset, view 30,15, image N x N) on ``cube4`` by the cycle rung and by
the rtl rung on each simulator (Icarus only up to ``--icarus-max``), median of
``--repeats`` after a warm-up (which also makes the cached simulator build, whose time is
reported apart), images and cycle counts checked equal.  Reported per case: wall seconds
and samples per wall second of both rungs and their ratio (goal: the cycle rung >= 10x the
rtl rung per simulated sample), the rtl frame split into host preparation and simulator
process, and the clocks the simulator ran (table loads plus the frame) per second of the
simulator process and, on Verilator, per second of the clock loop alone (goal: 100 k on the
lit P = 4 top over a 64^3 frame).  Everything runs on one thread (``HWSIM_THREADS=1``):
the Verilator model runs on one, and the cycle rung's compiled stage would otherwise use
both cores.  Nothing is asserted: benchmarks are not tests.
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
from hwsim.core.threads import using
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.bench import machine_info
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from rtl.frame import prepare
from rtl.rung import run_simulator

__all__ = ["run", "main", "GOAL_RATIO", "GOAL_CLOCKS_PER_SECOND"]

GOAL_RATIO = 10.0
#: Simulated clocks per second of the Verilator model (issue 17).
GOAL_CLOCKS_PER_SECOND = 100e3


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


def run(
    sizes: Sequence[int], simulators: Sequence[str], repeats: int, icarus_max: int = 16
) -> dict[str, Any]:
    """Measure every (size, simulator); returns the JSON-ready report."""
    cases = []
    for n in sizes:
        arch, volume, scene, tf, plan = _case(n)
        cycle_s, cyc = median_seconds(
            repeats, render_cycle, frame_of(scene, volume, tf, arch, plan)
        )
        for sim in simulators:
            if sim == "icarus" and n > icarus_max:
                continue
            t0 = time.perf_counter()
            _, first = _rtl_frame(sim, arch, volume, scene, tf, plan)  # warm-up: the build
            warm_up = time.perf_counter() - t0
            rtl_s, (res, timing) = median_seconds(
                repeats, _rtl_frame, sim, arch, volume, scene, tf, plan
            )
            sim_s = timing.get("sim_seconds")
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
                "rtl_build_seconds": first["build_seconds"],
                "rtl_warm_up_seconds": warm_up,
                "rtl_simulated_clocks_per_second": timing["clocks"] / timing["run_seconds"],
                "rtl_clock_loop_clocks_per_second": timing["clocks"] / sim_s if sim_s else None,
                "goal_clocks_per_second": GOAL_CLOCKS_PER_SECOND,
            }
            cases.append(case)
            loop = case["rtl_clock_loop_clocks_per_second"]
            print(
                f"{n:>3}^3 {sim:<9} cycle {case['cycle_samples_per_second'] / 1e3:8.1f} k/s  "
                f"rtl {case['rtl_samples_per_second'] / 1e3:8.1f} k/s  "
                f"ratio {case['ratio']:6.1f}x  rtl frame {rtl_s:6.2f} s  "
                f"clocks/s {case['rtl_simulated_clocks_per_second'] / 1e3:6.1f} k"
                + (f" (loop {loop / 1e3:.1f} k)" if loop else "")
                + f"  build {first['build_seconds']:.0f} s  identical {case['identical']}",
                file=sys.stderr,
            )
    return {
        "schema": 2,
        "benchmark": "cycle-vs-rtl",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "scene": "head phantom, ct preset, lit composite, view 30,15, image N x N, cube4",
        "repeats": repeats,
        "threads": 1,
        "cases": cases,
    }


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[16, 64, 128])
    p.add_argument("--simulators", nargs="+", default=["verilator", "icarus"])
    p.add_argument("--icarus-max", type=int, default=16)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    with using(1):
        report = run(args.sizes, args.simulators, args.repeats, args.icarus_max)
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
