"""Functional-rung speed against the golden renderer on the same scene, in one run.

Usage::

    .venv/bin/python benchmarks/bench_functional.py [--sizes 64 128] [--arch volumepro500]
                                                    [--out FILE.json]

For each size the CT-like head phantom is rendered (composite + Phong, ``ct`` preset,
256x256) by the float64 golden renderer at the architecture's sample positions, by the
fixed-point functional rung at the same positions (its compiled composite stage,
``models/fused.py``, and block leaping), by the functional rung running the chain of
vectorised unit calls instead (``compiled=False``), and by the reference loop: the unit
chain with the work skipping off too (``leap_blocks=False``: every planned sample
through the back end).  After one warm-up render each (which fills the per-volume caches
and loads or compiles the kernel: ``first_call_seconds``), the four are timed in
interleaved rounds (``--repeats`` rounds, median reported) so that load from other
processes on the shared machine falls on all alike; the load average is recorded before
and after.  The functional image, samples, rays and cycles are checked identical to the
chain's and the reference's.  The issue's goal is a ratio (golden seconds /
functional seconds) of at least 2; ``cpu_ratio`` is the same from CPU (user + system)
seconds, steadier than wall time when other processes share the cores.
``render_golden`` builds its ``SamplePlan`` inside the call while the functional rung is
handed one, so ``ratio_with_plan`` also charges the functional frame the median time of
building its plan (``plan_seconds``, timed in the same rounds).  Nothing here
is asserted: benchmarks are not tests.
"""

from __future__ import annotations

import argparse
import platform
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import os
import resource
import statistics
import time
from functools import partial

from benchmarks.report_io import write_report
from hwsim.golden import make_plan, render_golden
from hwsim.numerics import psnr
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom

__all__ = ["GOAL_RATIO", "run", "main"]

GOAL_RATIO = 2.0


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _interleaved(
    repeats: int, calls: dict[str, Any]
) -> tuple[dict[str, list[float]], dict[str, list[float]], dict, dict[str, float]]:
    """Wall and CPU (user + system) seconds of each named call over ``repeats`` rounds
    (one warm-up round first); returns both lists of times, the last results and each
    call's warm-up seconds."""
    results, first = {}, {}
    for name, fn in calls.items():
        start = time.perf_counter()
        results[name] = fn()
        first[name] = time.perf_counter() - start
    wall: dict[str, list[float]] = {name: [] for name in calls}
    cpu: dict[str, list[float]] = {name: [] for name in calls}
    for _ in range(repeats):
        for name, fn in calls.items():
            start, start_cpu = time.perf_counter(), _cpu_seconds()
            results[name] = fn()
            wall[name].append(time.perf_counter() - start)
            cpu[name].append(_cpu_seconds() - start_cpu)
    return wall, cpu, results, first


def run(sizes: Sequence[int], arch_name: str, repeats: int, image: int) -> dict[str, Any]:
    """Measure every size; returns the JSON report."""
    from models.frame import frame_of
    from models.functional import render_functional

    arch = resolve_arch(arch_name)
    cases = []
    for n in sizes:
        volume = make_phantom("head", size=n)
        scene = Scene(
            transfer=TransferSpec(preset="ct"),
            view=ViewSpec(azimuth=30, elevation=15, width=image, height=image, zoom=1.3),
        )
        tf = resolve_transfer(scene.transfer, volume)
        plan = make_plan(scene, volume, arch.order)
        frame = frame_of(scene, volume, tf, arch, plan)
        load_before = os.getloadavg()
        times, cpu, out, first = _interleaved(
            repeats,
            {
                "golden": partial(render_golden, scene, volume, tf, sampling=arch.order),
                # render_golden builds its plan inside the call; the functional rung is
                # handed one: time building it too, for the frame-for-frame ratio.
                "plan": partial(make_plan, scene, volume, arch.order),
                "functional": partial(render_functional, frame),
                "chain": partial(render_functional, frame, compiled=False),
                "reference": partial(render_functional, frame, leap_blocks=False, compiled=False),
            },
        )
        load_after = os.getloadavg()
        g_s, f_s, c_s, r_s = (
            statistics.median(times[k]) for k in ("golden", "functional", "chain", "reference")
        )
        g_cpu, f_cpu = (statistics.median(cpu[k]) for k in ("golden", "functional"))
        p_s = statistics.median(times["plan"])
        golden, fixed, ref = out["golden"], out["functional"], out["reference"]

        def same(a, b) -> bool:
            return bool(
                np.array_equal(a.image, b.image)
                and (a.samples, a.rays, a.cycles) == (b.samples, b.rays, b.cycles)
            )

        cases.append(
            {
                "size": n,
                "image": image,
                "arch": arch.name,
                "samples": fixed.samples,
                "simulated_samples": fixed.simulated,
                "golden_samples": golden.samples,
                "golden_seconds": g_s,
                "golden_samples_per_second": golden.samples / g_s,
                "functional_seconds": f_s,
                "functional_samples_per_second": fixed.samples / f_s,
                "first_call_seconds": first["functional"],
                "chain_seconds": c_s,
                "speedup_over_chain": c_s / f_s,
                "identical_to_chain": same(fixed, out["chain"]),
                "reference_seconds": r_s,
                "speedup_over_reference": r_s / f_s,
                "identical_to_reference": same(fixed, ref),
                "ratio": g_s / f_s,
                "plan_seconds": p_s,
                "ratio_with_plan": g_s / (f_s + p_s),
                "goal_ratio": GOAL_RATIO,
                "goal_met": g_s / f_s >= GOAL_RATIO,
                "psnr_db": psnr(golden.image, fixed.image),
                "simulated_fps": arch.clock_hz / fixed.cycles,
                "golden_cpu_seconds": g_cpu,
                "functional_cpu_seconds": f_cpu,
                "cpu_ratio": g_cpu / f_cpu,
                "seconds_all": {k: v for k, v in times.items()},
                "cpu_seconds_all": {k: v for k, v in cpu.items()},
                "load_average_before": list(load_before),
                "load_average_after": list(load_after),
            }
        )
    return {
        "schema": 3,
        "benchmark": "functional-vs-golden",
        "machine": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "processor": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
        },
        "cases": cases,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    parser.add_argument("--arch", default="volumepro500")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--image", type=int, default=256)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    report = run(args.sizes, args.arch, args.repeats, args.image)
    print(
        f"{'case':<22}{'golden s':>10}{'funct s':>10}{'Msamp/s':>9}{'chain s':>9}{'ref s':>9}"
        f"{'ratio':>8}{'+plan':>7}{'cpu':>6}{'goal':>6}{'PSNR':>7}{'same':>6}"
    )
    for c in report["cases"]:
        same = c["identical_to_reference"] and c["identical_to_chain"]
        print(
            f"{c['size']}^3 {c['arch']:<15}{c['golden_seconds']:>10.3f}"
            f"{c['functional_seconds']:>10.3f}"
            f"{c['functional_samples_per_second'] / 1e6:>9.2f}{c['chain_seconds']:>9.3f}"
            f"{c['reference_seconds']:>9.3f}{c['ratio']:>8.2f}{c['ratio_with_plan']:>7.2f}"
            f"{c['cpu_ratio']:>6.2f}"
            f"{'yes' if c['goal_met'] else 'no':>6}{c['psnr_db']:>7.1f}"
            f"{'yes' if same else 'NO':>6}"
        )
    print(
        "ratio = golden seconds / functional seconds (goal >= 2); +plan = the same with the "
        "functional frame charged its plan's construction; chain = unit chain "
        "(compiled=False); ref = unit chain, no work skipping"
    )
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
