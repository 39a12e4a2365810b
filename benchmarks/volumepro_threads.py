"""The VolumePro family's cycle rung on one thread and on two (``HWSIM_THREADS``).

On the speed table's frame (``speed_rows._machine_case``: head phantom, ``ct`` preset,
composite + Phong, N^3 to a 256^2 image), in one process, one frame on one thread and one
on two, alternated ``--repeats`` times: the smallest wall time of each and their ratio,
the CPU time of the process and of the frame's own thread (``time.thread_time``: what
stays on it; the rest ran on the helper threads of models/machines/volumepro/threads.py)
the CPU each helper thread spent (``helper_cpu_s``, by thread name, read as each ends)
and whether image, cycles and counters agree.  On a shared machine the wall times
measure the other jobs too: the load average before and after is recorded, and
``cpu_1 / main_thread_cpu_2`` and ``quiet_bound`` (``cpu_1`` over the longest of the
three threads' CPU and half the process's) bound the ratio a quiet machine could give::

    .venv/bin/python benchmarks/volumepro_threads.py --sizes 128 256 \
        --out benchmarks/results/volumepro-threads.json
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from benchmarks.speed_rows import _machine_case
from hwsim.core.threads import using as using_threads

#: CPU seconds of the helper threads that ended, by name (``hwsim-steps``, ...).
_HELPER_CPU: Counter = Counter()


def _counted_run(run):
    """``threading.Thread.run`` that adds the thread's CPU time to :data:`_HELPER_CPU`
    as it ends (helper threads start and end within a frame)."""

    def counted(self) -> None:
        try:
            run(self)
        finally:
            _HELPER_CPU[self.name.split("_")[0]] += time.thread_time()

    return counted


def _timed(threads: int, fn) -> tuple[float, float, float, object, dict]:
    with using_threads(threads):
        _HELPER_CPU.clear()
        wall, cpu, own = time.perf_counter(), time.process_time(), time.thread_time()
        out = fn()
        return (
            time.perf_counter() - wall,
            time.process_time() - cpu,
            time.thread_time() - own,
            out,
            dict(_HELPER_CPU),
        )


def measure(arch: str, n: int, repeats: int) -> dict:
    """One machine and size: one and two threads alternated, smallest times."""
    from models.cycle import render_cycle

    frame = _machine_case(arch, n, 256)[-1]
    render_cycle(frame)  # compiled code loaded, memory image kept
    threading.Thread.run = _counted_run(run := threading.Thread.run)
    load = os.getloadavg()[0]
    got: dict[int, list] = {1: [], 2: []}
    try:
        for _ in range(repeats):
            for threads in (1, 2):
                got[threads].append(_timed(threads, lambda: render_cycle(frame)))
    finally:
        threading.Thread.run = run
    row: dict = {"arch": arch, "size": n, "load_before": load, "load_after": os.getloadavg()[0]}
    for threads, runs in got.items():
        row[f"threads_{threads}"] = {
            "wall_s": min(r[0] for r in runs),
            "walls_s": [round(r[0], 3) for r in runs],
            "cpu_s": min(r[1] for r in runs),
            "main_thread_cpu_s": min(r[2] for r in runs),
            "helper_cpu_s": {k: min(r[4].get(k, 0.0) for r in runs) for k in runs[-1][4]},
        }
    one, two = got[1][-1][3], got[2][-1][3]
    row["same_bits"] = bool(
        np.array_equal(one.image, two.image)
        and one.cycles == two.cycles
        and one.counters == two.counters
    )
    row["wall_1_vs_2"] = row["threads_1"]["wall_s"] / row["threads_2"]["wall_s"]
    row["cpu_1_vs_main_thread_2"] = (
        row["threads_1"]["cpu_s"] / row["threads_2"]["main_thread_cpu_s"]
    )
    two = row["threads_2"]
    longest = max(two["main_thread_cpu_s"], *two["helper_cpu_s"].values(), two["cpu_s"] / 2)
    row["quiet_bound"] = row["threads_1"]["cpu_s"] / longest
    return row


def _cpus(cpu: dict) -> str:
    return ", ".join(f"{name} {seconds:.2f} s" for name, seconds in sorted(cpu.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arch", default="volumepro500")
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows = []
    for n in args.sizes:
        row = rows.append(measure(args.arch, n, args.repeats)) or rows[-1]
        print(
            f"{args.arch} {n}^3: 2 threads {row['wall_1_vs_2']:.2f}x one (wall, smallest of "
            f"{args.repeats}: {row['threads_1']['wall_s']:.2f} s vs "
            f"{row['threads_2']['wall_s']:.2f} s); frame thread CPU "
            f"{row['threads_2']['main_thread_cpu_s']:.2f} s of one thread's "
            f"{row['threads_1']['cpu_s']:.2f} s ({row['cpu_1_vs_main_thread_2']:.2f}x); "
            f"helpers {_cpus(row['threads_2']['helper_cpu_s'])}; quiet bound "
            f"{row['quiet_bound']:.2f}x; "
            f"same bits {row['same_bits']}; load {row['load_before']:.2f} -> "
            f"{row['load_after']:.2f}",
            flush=True,
        )
    write_report({"rows": rows}, args.out)


if __name__ == "__main__":
    main()
