"""VIZARD II on the real CT: early ray termination and space leaping speed-ups, cache hit rate.

Usage::

    .venv/bin/python benchmarks/vizard2_ct.py [--image 128] [--cache-sets 4 4 4]
        [--volume ../shared/data/ct_cranium.nrrd] [--out benchmarks/results/vizard2-ct.json]

Renders the CT (composite, CT preset, Phong, ERT threshold 0.95, view 30,15, zoom 1) on
``vizard2`` at cycle fidelity four times: brute force (no ERT, no leaping hardware), ERT
only, space leaping only, both.  Every image must equal the functional rung's (checked);
reported per variant: issued samples, cycles, fps at the clock, cache hit rate, SDRAM row
hit rate, the speed-up against brute force.  The cycles come from the model's mechanisms
(docs/cycle.md, VIZARD II section); nothing is fitted.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import read_volume
from models.frame import frame_of

VARIANTS = {
    "brute force": (False, False),
    "ERT": (True, False),
    "space leaping": (False, True),
    "ERT + space leaping": (True, True),
}


def run(volume_path: Path, image: int, cache_sets: Sequence[int]) -> dict[str, Any]:
    from models.cycle import render_cycle
    from models.functional import render_functional

    volume = read_volume(volume_path)
    base = resolve_arch("vizard2")
    base = dataclasses.replace(base, buffers={**base.buffers, "cache_sets": list(cache_sets)})
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=image, height=image, zoom=1.0),
        render=RenderSpec(mode="composite", early_termination=0.95),
    )
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, "ray")
    fixed = render_functional(frame_of(scene, volume, tf, base, plan))
    rows = []
    for name, (ert, leap) in VARIANTS.items():
        arch = dataclasses.replace(base, early_termination=ert, space_leaping=leap)
        start = time.perf_counter()
        result = render_cycle(frame_of(scene, volume, tf, arch, plan))
        wall = time.perf_counter() - start
        c = result.counters
        rows.append(
            {
                "variant": name,
                "early_termination": ert,
                "space_leaping": leap,
                "identical_to_functional": bool(np.array_equal(result.image, fixed.image)),
                "planned_samples": plan.samples,
                "issued_samples": c["frame.issued_samples"],
                "composited_samples": result.samples,
                "cycles": result.cycles,
                "fps": arch.clock_hz / result.cycles,
                "cycles_per_sample": result.cycles / c["frame.issued_samples"],
                "cache_hit_rate": result.derived["hit_rates"]["cache"],
                "lookups_per_sample": c["cache.lookups"] / c["frame.issued_samples"],
                "sdram_row_hit_rate": c["memory.row_hits"] / c["memory.bursts"],
                "sdram_data_bus_busy": c["memory.data_busy_cycles"] / result.cycles,
                "wall_seconds": wall,
            }
        )
        print(
            f"{name:<20} {result.cycles:>12,} cycles {rows[-1]['fps']:6.2f} fps "
            f"hit {rows[-1]['cache_hit_rate']:.3f} identical {rows[-1]['identical_to_functional']}",
            file=sys.stderr,
        )
    brute = rows[0]["cycles"]
    for row in rows:
        row["speedup"] = brute / row["cycles"]
    return {
        "schema": 1,
        "benchmark": "vizard2-ct",
        "scene": (
            f"{volume_path.name} {list(volume.shape)}, composite, CT preset, Phong, ERT 0.95, "
            f"view 30,15, zoom 1, image {image}^2; vizard2 (P={base.pipelines}, "
            f"{base.clock_hz / 1e6:g} MHz), cache_sets {list(cache_sets)}"
        ),
        "rows": rows,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--image", type=int, default=128)
    parser.add_argument("--cache-sets", type=int, nargs=3, default=[4, 4, 4])
    parser.add_argument(
        "--volume",
        type=Path,
        default=Path(__file__).resolve().parents[1] / "../shared/data/ct_cranium.nrrd",
    )
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    report = run(args.volume, args.image, args.cache_sets)
    for row in report["rows"]:
        print(f"{row['variant']:<20} speed-up {row['speedup']:.2f}x")
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
