"""Cycle-rung speed: simulated samples per wall second, against the functional rung and RTL.

Usage::

    .venv/bin/python benchmarks/bench_cycle.py [--sizes 128 256] [--pipelines 4]
                                               [--repeats 3] [--memory] [--out FILE.json]

For each size the CT-like head phantom is rendered (composite + Phong, ``ct`` preset,
image N x N) on a ``cube4`` of ``--pipelines`` pipelines by the functional rung and by
the cycle rung, timed in the same run (median of ``--repeats`` after a warm-up), with
the images checked bit-identical.  Reported: samples per wall second of each rung, their
ratio, simulated cycles per wall second, and the ratio to RTL simulation, taken from the
Verilator + cocotb figure of shared/docs/toolchain.md (~30 k cycles/s with a per-cycle
Python driver) until the rtl rung measures its own.  ``--memory`` adds the peak resident
set of a cycle render in a fresh subprocess (VmHWM) against the budget of the issue:
4 x the volume's bytes + 1 GiB, and against issue 18's 1.5 GB for a 512^3 frame.
Nothing is asserted: benchmarks are not tests.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import median_seconds, write_report
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of

__all__ = ["run", "main", "RTL_CYCLES_PER_SECOND", "GOAL_SAMPLES_PER_SECOND", "GOAL_RTL_RATIO"]

#: Verilator + cocotb, per-cycle Python driver: shared/docs/toolchain.md.
RTL_CYCLES_PER_SECOND = 30e3
GOAL_SAMPLES_PER_SECOND = 5e6
GOAL_RTL_RATIO = 30.0
#: Issue 18: the peak memory of a 512^3 cycle frame.
GOAL_PEAK_512_BYTES = 1.5e9


def _case(n: int, pipelines: int):
    arch = dataclasses.replace(resolve_arch("cube4"), pipelines=pipelines)
    volume = make_phantom("head", size=n)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=n, height=n, zoom=1.3),
    )
    tf = resolve_transfer(scene.transfer, volume)
    return arch, volume, scene, tf, make_plan(scene, volume, arch.order)


def peak_rss(n: int, pipelines: int) -> dict[str, Any]:
    """Peak resident set of one cycle render of size ``n`` in a fresh process."""
    root = str(Path(__file__).resolve().parents[1])
    code = "\n".join(
        [
            f"import sys; sys.path.insert(0, {root!r})",
            "from benchmarks.bench_cycle import _case",
            "from models.cycle import render_cycle",
            "from models.frame import frame_of",
            f"arch, vol, scene, tf, plan = _case({n}, {pipelines})",
            "render_cycle(frame_of(scene, vol, tf, arch, plan))",
            "print(vol.data.nbytes)",
            "print([l for l in open('/proc/self/status') if l.startswith('VmHWM')][0].split()[1])",
        ]
    )
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    volume_bytes, hwm_kib = (int(x) for x in out.stdout.split())
    budget = 4 * volume_bytes + (1 << 30)
    return {
        "size": n,
        "volume_bytes": volume_bytes,
        "peak_rss_bytes": hwm_kib * 1024,
        "budget_bytes": budget,
        "within_budget": hwm_kib * 1024 <= budget,
        "goal_512_bytes": GOAL_PEAK_512_BYTES,
        "wall_seconds": time.perf_counter() - start,
    }


def run(sizes: Sequence[int], pipelines: int, repeats: int, memory: bool) -> dict[str, Any]:
    from models.cycle import render_cycle
    from models.functional import render_functional

    cases = []
    for n in sizes:
        arch, volume, scene, tf, plan = _case(n, pipelines)
        frame = frame_of(scene, volume, tf, arch, plan)
        f_s, fixed = median_seconds(repeats, render_functional, frame)
        c_s, cycle = median_seconds(repeats, render_cycle, frame)
        cycles_per_s = cycle.cycles / c_s
        cases.append(
            {
                "size": n,
                "pipelines": pipelines,
                "samples": cycle.samples,
                "cycles": cycle.cycles,
                "bit_identical": bool(np.array_equal(fixed.image, cycle.image)),
                "functional_seconds": f_s,
                "functional_samples_per_second": fixed.samples / f_s,
                "cycle_seconds": c_s,
                "cycle_samples_per_second": cycle.samples / c_s,
                "cycle_over_functional_speed": f_s / c_s,
                "simulated_cycles_per_second": cycles_per_s,
                "rtl_reference_cycles_per_second": RTL_CYCLES_PER_SECOND,
                "ratio_to_rtl": cycles_per_s / RTL_CYCLES_PER_SECOND,
                "goal_samples_per_second": GOAL_SAMPLES_PER_SECOND,
                "goal_met": cycle.samples / c_s >= GOAL_SAMPLES_PER_SECOND,
                "rtl_goal_met": cycles_per_s / RTL_CYCLES_PER_SECOND >= GOAL_RTL_RATIO,
            }
        )
    report: dict[str, Any] = {
        "schema": 1,
        "benchmark": "cycle-rung",
        "machine": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "processor": platform.processor() or platform.machine(),
        },
        "cases": cases,
    }
    report["elision"] = [elision(n, pipelines, repeats) for n in sizes]
    if memory:
        report["memory"] = [peak_rss(n, pipelines) for n in sizes]
    return report


def elision(n: int, pipelines: int, repeats: int) -> dict[str, Any]:
    """Wall time of the elaborated-as-needed model against ``elaborate_all`` (same image
    and cycles, checked), for an unlit composite scene and a MIP scene."""
    from models.cycle import render_cycle

    arch, volume, scene, tf, plan = _case(n, pipelines)
    out: dict[str, Any] = {"size": n}
    for label, sc in (
        (
            "unlit",
            dataclasses.replace(scene, render=dataclasses.replace(scene.render, lighting=False)),
        ),
        ("mip", dataclasses.replace(scene, render=dataclasses.replace(scene.render, mode="mip"))),
        ("lit", scene),
    ):
        frame = frame_of(sc, volume, tf, arch, plan)
        lean_s, lean = median_seconds(repeats, render_cycle, frame)
        full_s, full = median_seconds(repeats, render_cycle, frame, elaborate_all=True)
        out[label] = {
            "elided_units": lean.elided_units,
            "lean_seconds": lean_s,
            "full_seconds": full_s,
            "speedup": full_s / lean_s,
            "same_image": bool(np.array_equal(lean.image, full.image)),
            "same_cycles": lean.cycles == full.cycles,
            "transparent_samples_skipped": lean.counters.get(
                "simulation.transparent_samples_skipped", 0
            ),
        }
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--pipelines", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--memory", action="store_true")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    report = run(args.sizes, args.pipelines, args.repeats, args.memory)
    print(f"{'case':<10}{'funct Ms/s':>11}{'cycle Ms/s':>11}{'cyc/fn':>8}{'Mcyc/s':>8}{'xRTL':>8}")
    for c in report["cases"]:
        print(
            f"{c['size']}^3 P={c['pipelines']:<3}{c['functional_samples_per_second'] / 1e6:>11.2f}"
            f"{c['cycle_samples_per_second'] / 1e6:>11.2f}{c['cycle_over_functional_speed']:>8.2f}"
            f"{c['simulated_cycles_per_second'] / 1e6:>8.2f}{c['ratio_to_rtl']:>8.0f}"
            f"  identical={c['bit_identical']}"
        )
    for e in report["elision"]:
        for label in ("unlit", "mip", "lit"):
            x = e[label]
            print(
                f"{e['size']}^3 {label:<6} elision speed-up {x['speedup']:.2f}x "
                f"(elided {', '.join(x['elided_units']) or 'none'}; "
                f"same image {x['same_image']}, same cycles {x['same_cycles']})"
            )
    for m in report.get("memory", []):
        print(
            f"{m['size']}^3 peak RSS {m['peak_rss_bytes'] / 2**20:.0f} MiB "
            f"(budget {m['budget_bytes'] / 2**20:.0f} MiB)"
        )
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
