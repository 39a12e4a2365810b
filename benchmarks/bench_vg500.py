"""The vg500 top's rtl rung against the VolumePro 500 cycle rung, and its speed on Verilator.

Usage::

    .venv/bin/python benchmarks/bench_vg500.py [--sizes 16 64 128] [--volume head|ct]
        [--out FILE.json]

For each size the head phantom (``--volume ct``: the CT of ``../shared/data/
ct_cranium.nrrd`` resampled to ``N^3``, a measured volume) is rendered in MIP (view 30,15,
image N x N: unlit, docs/rtl.md) on ``volumepro500`` by
the cycle rung and by the rtl rung (Verilator; the first run builds, its time reported
apart).  Reported per size: both rungs' cycles (they differ: docs/rtl.md says why), the
cycles of the slice-FIFO rules (models/machines/volumepro/fifo_timing.py, the RTL's
structure on the cycle rung's SDRAM scheduler), the RTL's held clocks and bursts, the
image equality, the SDRAM checkers' counts, and the simulated clocks per second of the
Verilator clock loop (goal: 100 k over a 64^3 frame, build excluded) and of the whole
simulator process, per second of wall time and per second of the process's CPU time (its
hex-file loads included: the figure a loaded machine does not change), and the rtl rung's
wall time (build excluded) over the cycle rung's in the same run.  One thread (``HWSIM_THREADS=1``).
Nothing is asserted: benchmarks are not tests.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.core.threads import using
from hwsim.studies.bench import machine_info

__all__ = ["run", "main", "GOAL_CLOCKS_PER_SECOND"]

#: Simulated clocks per second of the Verilator model over a 64^3 frame (issue 35).
GOAL_CLOCKS_PER_SECOND = 100e3


def _frame(n: int, volume: str = "head", scratch: Path | None = None):
    import hwsim
    from hwsim.studies.rtl_diff import _frame as frame_of_scene

    spec = f"head:size={n}"
    if volume == "ct":
        from benchmarks.split_frame import resample_ct

        spec = str(resample_ct(n, scratch))
    scene = hwsim.load_scene(None, volume=spec, view=(30, 15), image=n, mode="mip")
    return frame_of_scene(scene, "volumepro500", None)


def run(n: int, volume: str = "head", scratch: Path | None = None) -> dict:
    """One size: the cycle rung, then the rtl rung (built on first use)."""
    from models.backend import Backend
    from models.cycle import render_cycle
    from models.machines.volumepro.cycle import SlabMachine
    from models.machines.volumepro.fifo_timing import slice_fifo_timing
    from rtl.vg500.frame import prepare_vg500
    from rtl.vg500.rung import run_vg500

    frame = _frame(n, volume, scratch)
    t0 = time.perf_counter()
    cycle = render_cycle(frame)
    t1 = time.perf_counter()
    fifo = slice_fifo_timing(SlabMachine(Backend(frame)))
    program = prepare_vg500(frame)
    rtl, timing = run_vg500(program)
    c = rtl.counters
    return {
        "size": n,
        "volume": volume,
        "cycle_rung": {
            "cycles": cycle.cycles,
            "stall_cycles": cycle.counters.get("memory.stall_cycles"),
            "bursts": cycle.counters.get("memory.bursts"),
            "activates": cycle.counters.get("memory.sdram.activates"),
            "refreshes": cycle.counters.get("memory.sdram.refreshes"),
            "seconds": t1 - t0,
        },
        "slice_fifo_rules": {"cycles": fifo.cycles, "stall_cycles": fifo.stall_cycles},
        "rtl": {
            "cycles": rtl.cycles,
            "hold_cycles": c["memory.hold_cycles"],
            "frame_refreshes": c["memory.sdram.frame_refreshes"],
            "bursts": c["memory.bursts"],
            **{k.rsplit(".", 1)[1]: v for k, v in c.items() if ".checker." in k},
            "build_seconds": timing["build_seconds"],
            "run_seconds": timing["run_seconds"],
            "clocks": timing["clocks"],
            "clocks_per_second_loop": timing["clocks"] / timing["sim_seconds"],
            "clocks_per_second_process": timing["clocks"] / timing["run_seconds"],
            "cpu_seconds": timing["cpu_seconds"],
            "clocks_per_cpu_second_process": timing["clocks"] / timing["cpu_seconds"],
            "wall_over_cycle_rung": timing["run_seconds"] / (t1 - t0),
        },
        "image_equal": bool(np.array_equal(np.asarray(rtl.image), np.asarray(cycle.image))),
        "samples_equal": rtl.samples == cycle.samples,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[16, 64])
    parser.add_argument("--volume", choices=("head", "ct"), default="head")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    with using(1), tempfile.TemporaryDirectory() as scratch:
        rows = [run(n, args.volume, Path(scratch)) for n in args.sizes]
    for r in rows:
        print(
            f"{r['size']:>4}^3  cycle {r['cycle_rung']['cycles']:>9}"
            f"  slice-FIFO rules {r['slice_fifo_rules']['cycles']:>9}  rtl {r['rtl']['cycles']:>9}"
            f"  held {r['rtl']['hold_cycles']:>7}  image {'=' if r['image_equal'] else '!='}"
            f"  violations {r['rtl'].get('violations')}"
            f"  {r['rtl']['clocks_per_second_loop'] / 1e3:.0f} k clocks/s (loop)"
            f"  {r['rtl']['clocks_per_cpu_second_process'] / 1e3:.0f} k per CPU second"
            f"  wall {r['rtl']['wall_over_cycle_rung']:.1f}x the cycle rung's"
        )
    report = {
        "machine": machine_info(),
        "goal_clocks_per_second": GOAL_CLOCKS_PER_SECOND,
        "rows": rows,
    }
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
