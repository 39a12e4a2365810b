"""The bit-width trade: image error against golden as each datapath width shrinks.

``width_trade`` renders every scene with the functional datapath once per value of each
width knob (the others at the architecture's defaults) and compares against the float64
golden renderer at the *same* sample positions, so the error is purely numerical.  Next
to the error, each row prices the datapath (:mod:`hwsim.energy`, the machine's own node):
the machine's area with that width, and the energy its units spend per sample on the
scene (the memory traffic does not change with these widths; a frame's total is that
times its samples, plus the memories).  It writes ``widths.csv``, ``widths.json``,
``widths.png`` (PSNR against bits, one panel per knob) and ``widths-pareto.png`` (PSNR
against area and against energy per sample, every width of every knob, the Pareto front
drawn).  The fidelity-ladder trade (speed against error per rung) is
:mod:`hwsim.studies.trade.ladder`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hwsim.core.paths import atomic_write, output_folder
from hwsim.golden import make_plan, render_golden
from hwsim.numerics import max_abs_error, psnr, rmse
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import Scene
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.trade.files import write_rows
from hwsim.volumes.volume import Volume

__all__ = [
    "WIDTH_KNOBS",
    "WidthCase",
    "default_cases",
    "pareto_front",
    "width_trade",
    "write_width_trade",
]

#: Knob -> values swept (each list includes the VolumePro 500 default).
WIDTH_KNOBS: dict[str, list[int]] = {
    "interp.weight_bits": [2, 3, 4, 6, 8, 10],
    "gradient.normal_frac_bits": [3, 4, 6, 8, 10, 12],
    "classify.alpha_bits": [4, 6, 8, 10, 12],
    "classify.entries": [64, 256, 1024, 4096],
    "composite.acc_frac_bits": [12, 13, 14, 16, 20],
}


@dataclass(frozen=True)
class WidthCase:
    """One scene of the trade: a label, the scene and its loaded volume."""

    label: str
    scene: Scene
    volume: Volume


def default_cases(volumes: Sequence[str] = (), size: int = 64) -> list[WidthCase]:
    """Marschner-Lobb (composite + Phong, an opaque shell at rho = 0.5) plus each file."""
    from hwsim.spec.scene import TransferSpec, ViewSpec
    from hwsim.volumes import make_phantom, read_volume

    view = ViewSpec(azimuth=30, elevation=20, width=size, height=size, zoom=1.2)
    ml_tf = TransferSpec(
        preset=None,
        points=(
            (0.0, 0.0, 0.0, 0.0, 0.0),
            (0.45, 1.0, 0.8, 0.6, 0.0),
            (0.5, 1.0, 0.9, 0.8, 0.8),
            (1.0, 1.0, 1.0, 1.0, 0.8),
        ),
    )
    cases = [
        WidthCase(
            "marschner-lobb",
            Scene(transfer=ml_tf, view=view),
            make_phantom("marschner-lobb", size=40),
        )
    ]
    for path in volumes:
        volume = read_volume(path)
        cases.append(WidthCase(volume.name, Scene(view=view), volume))
    return cases


def width_trade(
    cases: Sequence[WidthCase],
    arch: ArchConfig,
    knobs: dict[str, list[int]] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict[str, Any]]:
    """One row per (knob, value, scene): PSNR, RMSE, max abs error, functional seconds."""
    from hwsim.energy import load_technology
    from hwsim.energy.model import machine_area, unit_joules_per_sample
    from models.datapath import Datapath, units_needed
    from models.frame import frame_of
    from models.functional import render_functional

    tech = load_technology(arch.technology)

    knobs = WIDTH_KNOBS if knobs is None else knobs
    rows: list[dict[str, Any]] = []
    total = len(cases) * sum(len(v) for v in knobs.values())
    done = 0
    for case in cases:
        tf = resolve_transfer(case.scene.transfer, case.volume, case.scene.base_dir)
        plan = make_plan(case.scene, case.volume, arch.order)
        golden = render_golden(case.scene, case.volume, tf, sampling=arch.order).image
        bits = case.volume.bits if case.volume.data.dtype.kind in "iu" else 0
        for knob, values in knobs.items():
            for value in values:
                dp = Datapath.from_arch(arch, bits, {knob: value})
                start = time.perf_counter()
                frame = frame_of(case.scene, case.volume, tf, arch, plan, datapath=dp)
                image = render_functional(frame).image
                seconds = time.perf_counter() - start
                used = [u for u, on in units_needed(case.scene, tf.modulates).items() if on]
                per_sample = unit_joules_per_sample(arch, dp, case.scene, used, tech)
                rows.append(
                    {
                        "knob": knob,
                        "value": value,
                        "scene": case.label,
                        "arch": arch.name,
                        "psnr_db": psnr(golden, image),
                        "rmse": rmse(golden, image),
                        "max_abs_error": max_abs_error(golden, image),
                        "functional_seconds": seconds,
                        "technology": tech.name,
                        "area_mm2": machine_area(arch, dp, tech)["total_mm2"],
                        "unit_energy_per_sample_joules": sum(per_sample.values()),
                    }
                )
                done += 1
                if progress is not None:
                    progress(done, total)
    return rows


def width_paths(out_dir: str | Path) -> dict[str, Path]:
    """The files :func:`write_width_trade` writes in ``out_dir``, by kind."""
    out = Path(out_dir)
    names = {"csv": "widths.csv", "json": "widths.json", "png": "widths.png"}
    return {kind: out / name for kind, name in (*names.items(), ("pareto", "widths-pareto.png"))}


def write_width_trade(rows: list[dict[str, Any]], out_dir: str | Path) -> dict[str, Path]:
    """Write ``widths.csv``, ``widths.json`` and ``widths.png`` into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_folder(out_dir)
    paths = width_paths(out_dir)
    write_rows(rows, paths["csv"], paths["json"])
    knobs = list(dict.fromkeys(r["knob"] for r in rows))
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(knobs), figsize=(3.2 * len(knobs), 3.0), squeeze=False)
    for ax, knob in zip(axes[0], knobs, strict=True):
        for scene in scenes:
            pts = [
                (r["value"], r["psnr_db"])
                for r in rows
                if r["knob"] == knob and r["scene"] == scene
            ]
            ax.plot([p[0] for p in pts], [min(p[1], 99.0) for p in pts], "o-", label=scene)
        ax.axhline(40.0, color="grey", lw=0.8, ls="--")
        if knob == "classify.entries":
            ax.set_xscale("log", base=2)
        ax.set_title(knob, fontsize=9)
        ax.set_xlabel("value")
        ax.set_ylabel("PSNR vs golden (dB)")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    with atomic_write(paths["png"]) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    _pareto_plot(plt, rows, knobs, scenes, paths["pareto"])
    return paths


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The points no other beats (lower cost ``x``, higher PSNR ``y``), by cost."""
    front: list[tuple[float, float]] = []
    for x, y in sorted(points, key=lambda p: (p[0], -p[1])):
        if not front or y > front[-1][1]:
            front.append((x, y))
    return front


def _pareto_plot(plt, rows, knobs, scenes, path: Path) -> None:
    """PSNR against area and against unit energy per sample, one colour per knob, one
    marker per scene, each scene's Pareto front as a line."""
    axes_of = (
        ("area_mm2", "area (mm^2)"),
        ("unit_energy_per_sample_joules", "unit energy per sample (J)"),
    )
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.0))
    markers = "osD^v<>"
    for ax, (key, label) in zip(axes, axes_of, strict=True):
        for k, knob in enumerate(knobs):
            for m, scene in enumerate(scenes):
                pts = [(r[key], min(r["psnr_db"], 99.0)) for r in rows
                       if r["knob"] == knob and r["scene"] == scene]  # fmt: skip
                ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=18, color=f"C{k}",
                           marker=markers[m % len(markers)],
                           label=knob if m == 0 else None)  # fmt: skip
        for m, scene in enumerate(scenes):
            front = pareto_front([(r[key], min(r["psnr_db"], 99.0)) for r in rows
                                  if r["scene"] == scene])  # fmt: skip
            ax.plot([p[0] for p in front], [p[1] for p in front], "k-", lw=0.8,
                    label="Pareto front" if m == 0 else None)  # fmt: skip
        ax.axhline(40.0, color="grey", lw=0.8, ls="--")
        ax.set_xlabel(f"{label}, {rows[0]['technology']}" if rows else label)
        ax.set_ylabel("PSNR vs golden (dB)")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    with atomic_write(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
