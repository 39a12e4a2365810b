"""Memory-model speed (bursts simulated per wall second) and the burst efficiency of each
layout, in one run.

Usage::

    .venv/bin/python benchmarks/bench_memory.py [--size 256] [--simpy-size 64] [--out FILE.json]

Part 1 times the cycle-exact scheduler (``hwsim.memory.schedule_bursts``) on a whole frame
of the VolumePro 500 layout (``--size``^3, every module, each principal axis) and on a
row-thrashing stream, and the SimPy form (``hwsim.memory.simulate_events``) on the same
layout at ``--simpy-size``^3 with the cycle form on that same stream, so the ratio compares
like with like.  Part 2 reports the efficiency (data-bus busy / elapsed) of every layout
and machine per axis, with where the rest went.  Nothing is asserted: benchmarks are not
tests.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import simpy

from benchmarks.report_io import write_report
from hwsim.memory import (
    MemoryConfig,
    SdramConfig,
    SdramStats,
    SdramTransactionPort,
    parse_memory,
    schedule_bursts,
    simulate_events,
)
from hwsim.run.fidelity import resolve_arch
from models.memory_streams import module_streams

__all__ = ["run", "main"]

AXES = ("x", "y", "z")


def _arch_memory(name: str) -> MemoryConfig:
    arch = resolve_arch(name)
    return parse_memory(arch.memory, source=arch.source)


def _time(fn, *args, **kwargs) -> tuple[float, Any]:
    start = time.perf_counter()
    result = fn(*args, **kwargs)
    return time.perf_counter() - start, result


def _port_run(cfg: SdramConfig, bank: np.ndarray, row: np.ndarray, batch: int) -> int:
    """Read a stream through SdramTransactionPort, ``batch`` bursts per SimPy event."""
    env = simpy.Environment()
    port = SdramTransactionPort(env, cfg)

    def reader():
        for k in range(0, bank.size, batch):
            yield port.read(bank[k : k + batch], row[k : k + batch])

    env.process(reader())
    env.run()
    return int(env.now)


def _speed(size: int, simpy_size: int) -> dict[str, Any]:
    mem = _arch_memory("volumepro500")
    cases = []
    warm_up_s, _ = _time(schedule_bursts, mem.sdram, [0], [0])  # load (or compile) the loop
    for axis in AXES:
        gen_s, streams = _time(module_streams, mem, size, axis)
        bursts = sum(len(s) for s in streams)
        start = time.perf_counter()
        for s in streams:
            schedule_bursts(mem.sdram, s.bank, s.row)
        sched_s = time.perf_counter() - start
        cases.append(
            {
                "stream": f"volumepro500 {size}^3 axis {axis}, all modules",
                "bursts": bursts,
                "stream_seconds": gen_s,
                "cycle_seconds": sched_s,
                "cycle_bursts_per_second": bursts / sched_s,
            }
        )
    n = 500_000
    thrash_s, _ = _time(schedule_bursts, mem.sdram, np.zeros(n, int), np.arange(n) % 2)
    cases.append(
        {
            "stream": "row-thrashing, one bank",
            "bursts": n,
            "cycle_seconds": thrash_s,
            "cycle_bursts_per_second": n / thrash_s,
        }
    )
    comparisons = []
    for axis in AXES:
        s = module_streams(mem, simpy_size, axis)[0]
        c_s, cyc = _time(schedule_bursts, mem.sdram, s.bank, s.row)
        e_s, ev = _time(simulate_events, mem.sdram, s.bank, s.row)
        p_s, _ = _time(_port_run, mem.sdram, s.bank, s.row, 64)
        comparisons.append(
            {
                "stream": f"volumepro500 {simpy_size}^3 axis {axis}, module 0",
                "bursts": len(s),
                "cycle_bursts_per_second": len(s) / c_s,
                "simpy_bursts_per_second": len(s) / e_s,
                "cycle_over_simpy_speed": e_s / c_s,
                "port_batch_bursts": 64,
                "port_bursts_per_second": len(s) / p_s,
                "same_completion_cycles": bool(np.array_equal(cyc.data_end, ev.data_end)),
            }
        )
    return {"warm_up_seconds": warm_up_s, "cycle": cases, "simpy_vs_cycle": comparisons}


def _layouts(size: int) -> list[dict[str, Any]]:
    vp500 = _arch_memory("volumepro500")
    cube4_dev = dataclasses.replace(vp500.sdram, burst_length=1)
    layouts = [
        ("volumepro500", vp500),
        (
            "volumepro500, refresh off",
            dataclasses.replace(vp500, sdram=dataclasses.replace(vp500.sdram, t_refi=0)),
        ),
        ("em-cube", _arch_memory("em-cube")),
        ("volumepro1000", _arch_memory("volumepro1000")),
        ("no bank skew (block)", dataclasses.replace(vp500, skew="block")),
        ("cube4 skew on SDRAM, burst 1", MemoryConfig(modules=4, skew="cube4", sdram=cube4_dev)),
    ]
    rows = []
    for label, mem in layouts:
        n = size if mem.skew != "cube4" else min(size, 64)
        for axis in AXES:
            stats = SdramStats.combine(
                [
                    schedule_bursts(mem.sdram, s.bank, s.row).stats
                    for s in module_streams(mem, n, axis)
                ]
            )
            rows.append(
                {
                    "layout": label,
                    "size": n,
                    "axis": axis,
                    "efficiency": stats.data_busy_cycles / (stats.elapsed_cycles * mem.modules),
                    **{k: v for k, v in dataclasses.asdict(stats).items()},
                }
            )
    return rows


def run(size: int, simpy_size: int, layout_size: int) -> dict[str, Any]:
    """Measure; returns the JSON report."""
    return {
        "schema": 1,
        "benchmark": "memory",
        "command": " ".join(sys.argv),
        "machine": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "processor": platform.processor() or platform.machine(),
        },
        "speed": _speed(size, simpy_size),
        "layouts": _layouts(layout_size),
        "defaults": dataclasses.asdict(SdramConfig()),
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256, help="frame side for the speed run")
    parser.add_argument("--simpy-size", type=int, default=64, help="frame side for SimPy")
    parser.add_argument("--layout-size", type=int, default=64, help="frame side per layout")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    report = run(args.size, args.simpy_size, args.layout_size)
    for c in report["speed"]["cycle"]:
        rate = c["cycle_bursts_per_second"] / 1e6
        print(f"{c['stream']:<44}{c['bursts']:>9} bursts {rate:6.2f} M/s")
    for c in report["speed"]["simpy_vs_cycle"]:
        print(
            f"{c['stream']:<44}SimPy {c['simpy_bursts_per_second'] / 1e3:7.1f} k/s, cycle form "
            f"{c['cycle_over_simpy_speed']:5.1f}x faster, "
            f"same cycles: {c['same_completion_cycles']}; "
            f"port (64/event) {c['port_bursts_per_second'] / 1e6:5.2f} M/s"
        )
    print(f"{'layout':<32}{'n':>5}{'axis':>5}{'efficiency':>11}{'bank stall':>11}{'refresh':>9}")
    for r in report["layouts"]:
        print(
            f"{r['layout']:<32}{r['size']:>5}{r['axis']:>5}{100 * r['efficiency']:>10.2f}%"
            f"{r['stall_bank_cycles']:>11}{r['stall_refresh_cycles']:>9}"
        )
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
