"""Cube-4 scaling study: frame cycles against pipeline count, from the cycle rung.

Usage::

    .venv/bin/python benchmarks/scaling_cube4.py [--sizes 64 128 256 512]
        [--pipelines 1 2 4 8 16 32 64] [--out benchmarks/results/cube4-scaling.json]
        [--plot FILE.png]

Each (size, P) renders the head phantom (MIP, view 30,20, image = size) on ``cube4`` with
P pipelines at cycle fidelity; MIP needs the fewest units, and the Cube-4 frame time does
not depend on the mode (the pipeline is fixed hardware).  Reported per case: cycles,
samples per cycle, efficiency = samples / (cycles P), and fps at 125 MHz.  Then:

* the pipelines x clock a 1024^3 frame needs for 30 fps, from the efficiency measured at
  the largest size and P (an extrapolation, said so), next to the closed form of the
  timing rules for an axis-aligned 1024^3 frame (``rule_cycles_1024``, docs/cycle.md).
  The closed form is not independent of the simulator: it calls the cycle rung's own
  ``cube4_latency``, which the simulated frame's pixel bus uses too, so its agreement
  with a simulated frame (``test_axis_aligned_cycle_count_has_its_closed_form``, the
  1024^3 frame of benchmarks/split_frame.py) is a consistency check (``RULE_NOTE``);
* ``cube4-teramac`` on a 128^3 head (its published figure: 0.65 s at 0.96 MHz), compared,
  not fitted.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of

CLAIM_SIZE, CLAIM_FPS = 1024, 30.0  # architectures.md 1.1 [V]
#: What ``rule_cycles_1024`` is (written beside it in the report).
RULE_NOTE = (
    "closed form n^2 C + cube4_latency(C) + n^2 of the timing rules for an axis-aligned "
    "dense frame; it calls the cycle rung's own cube4_latency (shared with the simulator's "
    "pixel bus), so agreement with a simulated frame is a consistency check, not an "
    "independent derivation"
)


def frame(n: int, arch, mode: str = "mip", view=(30, 20)):
    from models.cycle import render_cycle

    volume = make_phantom("head", size=n)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=view[0], elevation=view[1], width=n, height=n, zoom=1.2),
        render=RenderSpec(mode=mode),
    )
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, arch.order)
    start = time.perf_counter()
    result = render_cycle(frame_of(scene, volume, tf, arch, plan))
    return result, time.perf_counter() - start


def rule_cycles(n: int, P: int) -> int:
    """The model's timing rules for an axis-aligned n^3 frame (docs/cycle.md): the last
    slice's period starts at ``n n C``, its first pixels leave the pipeline latency later
    and the bus drains all ``n^2`` back to back.  The latency is the cycle rung's own
    :func:`~models.machines.cube4.timing.cube4_latency` (:data:`RULE_NOTE`)."""
    from models.machines.cube4.timing import cube4_latency

    C = -(-n // P)
    return n * n * C + cube4_latency(C) + n * n


def run(sizes: Sequence[int], pipelines: Sequence[int]) -> dict[str, Any]:
    base = resolve_arch("cube4")
    rows = []
    for n in sizes:
        for P in pipelines:
            arch = dataclasses.replace(base, pipelines=P)
            result, wall = frame(n, arch)
            rows.append(
                {
                    "size": n,
                    "pipelines": P,
                    "cycles": result.cycles,
                    "samples": result.samples,
                    "samples_per_cycle": result.samples / result.cycles,
                    "efficiency": result.samples / (result.cycles * P),
                    "fps_at_125MHz": base.clock_hz / result.cycles,
                    "wall_seconds": wall,
                }
            )
            print(
                f"{n}^3 P={P:<3} {result.cycles:>12,} cycles  "
                f"{rows[-1]['efficiency']:.3f} eff  {rows[-1]['fps_at_125MHz']:8.1f} fps",
                file=sys.stderr,
            )
    largest = max(sizes)
    ref = max((r for r in rows if r["size"] == largest), key=lambda r: r["pipelines"])
    needed = CLAIM_SIZE**3 * CLAIM_FPS / ref["efficiency"]
    claim = {
        "samples_per_second_needed": CLAIM_SIZE**3 * CLAIM_FPS,
        "efficiency_used": ref["efficiency"],
        "efficiency_from": f"{largest}^3, P={ref['pipelines']} (extrapolated to 1024^3)",
        "pipelines_x_clock_needed": needed,
        "examples": {f"P={P}": {"clock_hz_needed": needed / P} for P in (64, 128, 256, 512, 1024)},
        "rule_cycles_1024": {f"P={P}": rule_cycles(CLAIM_SIZE, P) for P in (64, 256, 1024)},
        "rule_cycles_1024_note": RULE_NOTE,
    }
    claim["rule_clock_for_30fps_hz"] = {
        k: v * CLAIM_FPS for k, v in claim["rule_cycles_1024"].items()
    }
    teramac = resolve_arch("cube4-teramac")
    t_result, _ = frame(128, teramac, mode="composite")
    seconds = t_result.cycles / teramac.clock_hz
    published = float(teramac.published["seconds_128"])
    return {
        "schema": 1,
        "benchmark": "cube4-scaling",
        "scene": "head phantom, MIP, view 30,20, image = size; cube4 at 125 MHz",
        "rows": rows,
        "claim_1024_at_30fps": claim,
        "teramac": {
            "size": 128,
            "cycles": t_result.cycles,
            "clock_hz": teramac.clock_hz,
            "seconds": seconds,
            "published_seconds": published,
            "published_cycles": published * teramac.clock_hz,
            "difference": seconds / published - 1.0,
        },
    }


def plot(report: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for n in sorted({r["size"] for r in report["rows"]}):
        rows = [r for r in report["rows"] if r["size"] == n]
        ax.plot(
            [r["pipelines"] for r in rows],
            [r["samples_per_cycle"] for r in rows],
            "o-",
            label=f"{n}^3",
        )
    ps = sorted({r["pipelines"] for r in report["rows"]})
    ax.plot(ps, ps, "k--", lw=0.8, label="linear (P samples/cycle)")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log", base=2)
    ax.set_xlabel("pipelines P")
    ax.set_ylabel("samples per cycle")
    ax.set_title("Cube-4 scaling (cycle rung)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256, 512])
    parser.add_argument("--pipelines", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--out", type=Path)
    parser.add_argument("--plot", type=Path)
    args = parser.parse_args(argv)
    report = run(args.sizes, args.pipelines)
    claim, tm = report["claim_1024_at_30fps"], report["teramac"]
    print(
        f"1024^3 at 30 fps needs P x f = {claim['pipelines_x_clock_needed']:.3g} samples/s "
        f"(efficiency {claim['efficiency_used']:.4f} from {claim['efficiency_from']})"
    )
    rules = ", ".join(f"{k} {v:,}" for k, v in claim["rule_cycles_1024"].items())
    print(f"1024^3 by the closed form of the rules (shares cube4_latency): {rules} cycles")
    print(
        f"cube4-teramac 128^3: {tm['cycles']:,} cycles = {tm['seconds']:.3f} s at 0.96 MHz "
        f"vs published {tm['published_seconds']} s ({tm['difference']:+.1%})"
    )
    write_report(report, args.out)
    if args.plot:
        plot(report, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
