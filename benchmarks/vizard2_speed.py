"""VIZARD II's cycle rung: the compiled ray loop against the unit chain, and timing-only.

On the speed table's frame (``speed_rows._machine_case``: head phantom, ``ct`` preset,
composite + Phong, N^3 to N^2, one thread), in one process: the cycle rung with its
compiled ray loop (``models/machines/vizard2/ray_kernel.py``), the reference unit chain
(``compiled=False``, once: it is slow) and the timing-only transaction rung, alternated;
median wall and CPU seconds, samples per second, the loop's speed-up over the chain and
timing-only over cycle, and whether the cycles agree.  CPU time is recorded beside wall
time because on a shared machine the wall time mostly measures the other jobs::

    .venv/bin/python benchmarks/vizard2_speed.py --sizes 128 256 \
        --out benchmarks/results/vizard2-speed.json
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from benchmarks.speed_rows import _machine_case
from hwsim.core.threads import using as using_threads


def _timed(fn) -> tuple[float, float, object]:
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - wall, time.process_time() - cpu, out


def measure(n: int, repeats: int) -> dict:
    """One size: the three runs, medians and ratios."""
    from models.cycle import render_cycle
    from models.transaction import timing_only

    frame = _machine_case("vizard2", n)[-1]
    runs = {
        "cycle": lambda: render_cycle(frame),
        "timing_only": lambda: timing_only(frame),
        "reference": lambda: render_cycle(frame, compiled=False),
    }
    runs["cycle"](), runs["timing_only"]()  # compiled code loaded, memory image kept
    times: dict[str, list] = {k: [] for k in runs}
    for k in range(repeats):
        for name, fn in runs.items():
            if name != "reference" or k == 0:
                times[name].append(_timed(fn))
    row: dict = {"size": n}
    for name, got in times.items():
        row[name] = {
            "wall_s": statistics.median(t[0] for t in got),
            "cpu_s": statistics.median(t[1] for t in got),
            "cycles": got[-1][2].cycles,
        }
    samples = times["cycle"][-1][2].samples
    cyc, ref, alone = row["cycle"], row["reference"], row["timing_only"]
    row.update(
        samples=samples,
        cycle_samples_per_s_cpu=samples / cyc["cpu_s"],
        cycle_samples_per_s_wall=samples / cyc["wall_s"],
        loop_vs_chain_cpu=ref["cpu_s"] / cyc["cpu_s"],
        loop_vs_chain_wall=ref["wall_s"] / cyc["wall_s"],
        timing_only_vs_cycle_cpu=cyc["cpu_s"] / alone["cpu_s"],
        timing_only_cycle_error=(alone["cycles"] - cyc["cycles"]) / cyc["cycles"],
        chain_cycles_equal=ref["cycles"] == cyc["cycles"],
    )
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows = []
    with using_threads(1):
        for n in args.sizes:
            rows.append(measure(n, args.repeats))
            print(
                f"{n}^3: {rows[-1]['cycle_samples_per_s_cpu'] / 1e6:.2f} M samples/s (CPU), "
                f"{rows[-1]['loop_vs_chain_cpu']:.1f}x the unit chain, timing-only "
                f"{rows[-1]['timing_only_vs_cycle_cpu']:.2f}x the cycle rung",
                flush=True,
            )
    load = os.getloadavg()
    write_report(
        {"note": f"one thread; load average {load[0]:.2f} at the end", "rows": rows}, args.out
    )


if __name__ == "__main__":
    main()
