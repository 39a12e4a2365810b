"""Published figures of the VolumePro family reproduced by the cycle rung's mechanisms.

Usage::

    .venv/bin/python benchmarks/published_figures.py [--size 256] [--ct PATH] [--out FILE]

(default ``--out``: benchmarks/results/published-figures.json)

For each machine whose arch file sets acceptance bands (``[published] tolerance``: the
VolumePro family) its figures at ``--size`` are measured on the cycle rung, from its
mechanisms only (pipelines, clock, SDRAM timing, buffers, pixel bus, latency; no
efficiency factor).  Those figures are ``peak`` or ``fitted`` (pipelines x clock was set
from them: docs/figures.md), so each row measures the modelled overheads, not the
machine's timing; on the scenario ``hwsim figures`` uses (:mod:`hwsim.studies.figures`: the
dense head phantom, one sample per voxel, the widest voxels).  The published values and
tolerances are read from the arch files: this script holds no figure of its own.

Published rates are for continuous rendering, so the figure uses the *frame period*:
the cycles between the ends of two frames rendered back to back on the same memory
controllers and pixel FIFO (the next frame's first slabs are read while the last slices
of this one are processed; this frame's pixels drain while the next is processed).  The
single-frame figure (fill, last slices, pixel-bus drain, latency in one frame) is
reported beside it.

Each row also lists where the cycles went (ideal sample clocks, memory stalls with the
SDRAM refresh and row-miss counts, pixel-bus drain, pipeline latency).  With ``--ct``
(default ``../shared/data/ct_cranium.nrrd`` when present) it adds the speed-ups of
VolumePro 1000's early ray termination and of space leaping (a feature the file leaves
off; ``[features] space_leaping = true`` turns it on) on the real CT, with the image
difference each causes, and what sectioning (64 beams) costs VolumePro 500.
tests/models/test_cycle_published.py asserts the tolerances
with :func:`measure`.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.golden import make_plan
from hwsim.run.fidelity import builtin_archs, render, resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.figures import figure_machine, figure_scene, figure_value, published_figures
from hwsim.volumes import load_volume, make_phantom, read_volume
from models.frame import frame_of

__all__ = ["acceptance_archs", "measure", "sectioning", "acceleration", "main"]

REPO = Path(__file__).resolve().parents[1]


def acceptance_archs() -> list[str]:
    """The built-in machines whose ``[published]`` table sets acceptance bands."""
    return [
        name
        for name, arch in builtin_archs().items()
        if any(f.tolerance is not None for f in published_figures(arch))
    ]


def _run(arch, scene, volume, **kw):
    from models.cycle import render_cycle

    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    start = time.perf_counter()
    result = render_cycle(frame_of(scene, volume, tf, machine, plan), **kw)
    return result, time.perf_counter() - start


def measure(arch: str, n: int = 256) -> dict[str, Any]:
    """The published figures of ``arch`` quoted at ``n^3``, on the scenario and machine
    ``hwsim figures`` measures them with (the head phantom, one sample per voxel, the
    widest voxels), at the cycle rung's back-to-back frame period, with where the cycles
    went.  Values and tolerances are the arch file's ``[published]`` table."""
    base = resolve_arch(arch)
    machine, scene = figure_machine(base), figure_scene(n)
    volume = load_volume(scene.volume, scene.base_dir)
    result = render(scene, fidelity="cycle", arch=machine, volume=volume, steady_state=True)
    c, wall = result.counters, result.wall_seconds
    period = c["frame.period_cycles"]
    figures = []
    for fig in published_figures(base):
        if fig.size != n or not fig.scenario.dense:
            continue
        value = figure_value(fig.metric, result, period)
        single = figure_value(fig.metric, result)
        figures.append(
            {
                "key": fig.key,
                "evidence": fig.evidence,
                "fitted_from": list(fig.fitted_from),
                "published": fig.value,
                "tolerance": fig.tolerance,
                "note": fig.note,
                "model": value,
                "difference": value / fig.value - 1.0,
                "within_tolerance": None
                if fig.tolerance is None
                else abs(value / fig.value - 1.0) <= fig.tolerance,
                "single_frame": single,
                "single_frame_difference": single / fig.value - 1.0,
            }
        )
    return {
        "arch": arch,
        "scene": scene.name,
        "figures": figures,
        "basis": "continuous rendering: cycles between the ends of two frames back to back",
        "size": n,
        "pipelines": machine.pipelines,
        "clock_hz": machine.clock_hz,
        "period_cycles": period,
        "cycles": result.cycles,
        "samples": result.samples,
        "breakdown": {
            "beam_clocks": c["pipeline.beam_cycles"],
            "memory_stall_cycles": c["memory.stall_cycles"],
            "pixel_bus_drain_cycles": c["pixel_bus.drain_cycles"],
            "pixel_bus_stall_cycles": c["pixel_bus.stall_cycles"],
            "pipeline_latency_cycles": c["pipeline.latency_cycles"],
            "sdram_bursts": c["memory.bursts"],
            "sdram_refreshes": c["memory.sdram.refreshes"],
            "sdram_refresh_cycles": c["memory.sdram.refresh_cycles"],
            "sdram_row_misses": c["memory.sdram.row_misses"],
            "sdram_row_conflicts": c["memory.sdram.row_conflicts"],
        },
        "wall_seconds": wall,
    }


def sectioning(n: int = 256, width: int = 64) -> dict[str, Any]:
    """What sectioning costs VolumePro 500 on a dense ``n^3`` volume at a sheared view
    (30/20 degrees, MIP): sections of ``width`` beams against none, continuous rate.
    No per-section overhead is published ([?]); the cost shown is the mechanisms':
    mini-block beams re-read at section overlaps, parked rays reloaded."""
    base = resolve_arch("volumepro500")
    volume = make_phantom("head", size=n)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=20, width=n, height=n, zoom=1.0),
        render=RenderSpec(mode="mip"),
    )
    out: dict[str, Any] = {"size": n, "section_width": width, "view": [30, 20]}
    for name, arch in (
        ("whole", base),
        ("sections", dataclasses.replace(base, section_width=width)),
    ):
        result, wall = _run(arch, scene, volume, steady_state=True)
        c = result.counters
        out[name] = {
            "period_cycles": c["frame.period_cycles"],
            "fps": base.clock_hz / c["frame.period_cycles"],
            "sections": c["section.count"],
            "sdram_bursts": c["memory.bursts"],
            "parked_rays": c["section.parked_rays"],
            "reload_cycles": c["section.reload_cycles"],
            "wall_seconds": wall,
        }
    whole, cut = out["whole"], out["sections"]
    out["reread_bursts"] = cut["sdram_bursts"] - whole["sdram_bursts"]
    out["slowdown"] = cut["period_cycles"] / whole["period_cycles"]
    return out


def acceleration(path: Path, size: int = 96) -> dict[str, Any]:
    """Speed-ups of VolumePro 1000's early ray termination and of space leaping on a real
    volume (composite, ``ct`` preset, lit, a 30/20 degree view, ``size``-pixel image)."""
    volume = read_volume(path)
    base = resolve_arch("volumepro1000")
    leaping = dataclasses.replace(base, space_leaping=True)

    def scene(threshold: float) -> Scene:
        return Scene(
            transfer=TransferSpec(preset="ct"),
            view=ViewSpec(azimuth=30, elevation=20, width=size, height=size, zoom=1.2),
            render=RenderSpec(mode="composite", lighting=True, early_termination=threshold),
        )

    runs = {
        "brute_force": _run(base, scene(1.0), volume),
        "ert_0.95": _run(base, scene(0.95), volume),
        "space_leaping": _run(leaping, scene(1.0), volume),
        "ert_0.95_and_space_leaping": _run(leaping, scene(0.95), volume),
    }
    brute = runs["brute_force"][0]
    out: dict[str, Any] = {"volume": path.name, "shape": list(volume.shape), "image": size}
    for name, (result, wall) in runs.items():
        diff = np.abs(result.image - brute.image)
        out[name] = {
            "cycles": result.cycles,
            "speedup": brute.cycles / result.cycles,
            "samples": result.samples,
            "sdram_bursts": result.counters["memory.bursts"],
            "max_image_difference": float(diff.max()),
            "pixels_changed": int(np.count_nonzero(np.any(diff > 0, axis=-1))),
            "wall_seconds": wall,
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--ct", type=Path, default=REPO.parent / "shared" / "data" / "ct_cranium.nrrd")
    ap.add_argument("--ct-image", type=int, default=96)
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks/results/published-figures.json")
    args = ap.parse_args(argv)
    rows = []
    for arch in acceptance_archs():
        row = measure(arch, args.size)
        rows.append(row)
        for fig in row["figures"]:
            band = "" if fig["tolerance"] is None else f", tolerance {fig['tolerance']:.0%}"
            print(
                f"{arch:14s} {fig['key']:20s} published {fig['published']:.4g}  model "
                f"{fig['model']:.4g}  ({fig['difference']:+.1%}{band}); single frame "
                f"{fig['single_frame']:.4g} ({fig['single_frame_difference']:+.1%})",
                file=sys.stderr,
            )
    report: dict[str, Any] = {"figures": rows}
    report["volumepro500_sectioning"] = sec = sectioning(args.size)
    print(
        f"volumepro500 sections of {sec['section_width']}: {sec['sections']['fps']:.2f} fps "
        f"against {sec['whole']['fps']:.2f} ({sec['reread_bursts']} bursts re-read)",
        file=sys.stderr,
    )
    if args.ct.exists():
        report["volumepro1000_acceleration"] = acc = acceleration(args.ct, args.ct_image)
        for name in ("ert_0.95", "space_leaping", "ert_0.95_and_space_leaping"):
            print(f"volumepro1000 {name}: {acc[name]['speedup']:.2f}x", file=sys.stderr)
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
