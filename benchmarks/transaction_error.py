"""Transaction-rung cycle error against the cycle rung: the measured table for the report.

Usage::

    .venv/bin/python benchmarks/transaction_error.py [--quick] [--out FILE.json]
    .venv/bin/python benchmarks/transaction_error.py --annotate FILE.json

For every case (phantoms head, ball, Marschner-Lobb at several parallel and perspective
views; the real CT and MR of ../shared/data when present; pipeline counts 4 and 8; the
Teramac machine; a shallow pixel FIFO; VolumePro 500 and EM-Cube; VolumePro 1000 and
VIZARD II with early ray termination and space leaping off and on) the cycle rung
renders the frame and the
transaction rung's event model times it; the relative error
``(transaction - cycle) / cycle`` is written per case, with the worst per architecture
family and per kind of view.

Every case also names its **independence** (:mod:`hwsim.studies.trade.independence`, read from
the code): on the Cube-4 family both rungs time the frame with the same functions
(``cube4_latency``, ``cube4_pixel_pushes``, ``freezing_fifo``, ``cube4_lanes``), so its
error is a consistency check, shown as ``consistency check (shared code: ...)``, not a
measurement; the VolumePro family and VIZARD II are ``partly shared`` (the SDRAM
controller, burst layouts, latencies and buffer sizes are one copy; the event models'
schedules, buffers, caches and pixel buses are their own).  ``--annotate FILE`` adds
those columns to an existing report without re-measuring.  The images are not compared
here: the transaction image is the functional rung's by construction
(``render_functional`` is called), and functional against cycle is tests/models'.
``--quick`` keeps the small phantoms only.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.core import env
from hwsim.core.errors import NotAvailableError
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.studies.bench import machine_info
from hwsim.studies.trade.independence import SHARED as SHARED_CODE
from hwsim.studies.trade.independence import (
    TRANSACTION_VS_CYCLE,
    shown_error,
    transaction_family,
)
from hwsim.volumes import make_phantom, read_volume
from models.cycle import render_cycle
from models.frame import frame_of
from models.functional import render_functional
from models.transaction import transaction_timing

__all__ = ["CONTRACT", "annotate", "cases", "measure", "run", "main"]

#: The issue's bound on the transaction rung's cycle error.
CONTRACT = 0.02
SHARED = env.value("HWSIM_SHARED_DATA") or (
    Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
)

PARALLEL = [(0, 0), (30, 20), (45, 0), (150, -30), (90, 45)]
PERSPECTIVE = [(-35, 10), (20, 15), (160, -20)]


def _scene(source, az, el, projection, image, *, mode="composite", preset="ct", zoom=1.2):
    spec = VolumeSpec(path=str(source)) if isinstance(source, Path) else VolumeSpec(phantom=source)
    return Scene(
        volume=spec,
        transfer=TransferSpec(preset=preset),
        view=ViewSpec(
            azimuth=az,
            elevation=el,
            width=image,
            height=image,
            zoom=zoom,
            projection=projection,
            distance=3.0,
        ),
        render=dataclasses.replace(Scene().render, mode=mode),
    )


@functools.cache
def _real_volumes() -> tuple[tuple[str, Path, Any, str], ...]:
    """The real CT and MR of ../shared/data that are present, read once:
    ``(file name, path, volume, transfer preset)``."""
    out = []
    for fname in ("ct_cranium.nrrd", "mr_brainsmall.nrrd"):
        path = SHARED / fname
        if path.is_file():
            out.append((fname, path, read_volume(path), "ct" if fname.startswith("ct") else "mr"))
    return tuple(out)


def cases(quick: bool = False) -> list[dict[str, Any]]:
    """The measured cases: name, volume, scene, architecture."""
    cube4 = resolve_arch("cube4")
    out = []
    sizes = [("head", 48, "ct", "composite"), ("ball", 40, "ct", "xray")]
    sizes += [("marschner-lobb", 41, "ct", "mip"), ("ball", 20, "ct", "xray")]
    if not quick:
        sizes.append(("head", 96, "ct", "composite"))
    for phantom, n, preset, mode in sizes:
        volume = make_phantom(phantom, size=n)
        for P in (4, 8):
            arch = dataclasses.replace(cube4, name=f"cube4-P{P}", pipelines=P)
            for projection, views in (("parallel", PARALLEL), ("perspective", PERSPECTIVE)):
                for az, el in views:
                    for image in (n, 2 * n) if projection == "perspective" else (n,):
                        scene = _scene(phantom, az, el, projection, image, mode=mode, preset=preset)
                        out.append(
                            {
                                "name": f"{phantom}{n} {projection} {az},{el} img{image} P{P}",
                                "volume": volume,
                                "scene": scene,
                                "arch": arch,
                                "projection": projection,
                            }
                        )
    head = make_phantom("head", size=64)
    shallow = dataclasses.replace(cube4, name="cube4-pixfifo64", buffers={"pixel_fifo_entries": 64})
    for az, el in [(0, 0), (30, 20)]:
        out.append(
            {
                "name": f"head64 parallel {az},{el} pixel FIFO 64",
                "volume": head,
                "scene": _scene("head", az, el, "parallel", 64),
                "arch": shallow,
                "projection": "parallel",
            }
        )
    if not quick:
        teramac = resolve_arch("cube4-teramac")
        out.append(
            {
                "name": "head128 parallel 30,20 teramac",
                "volume": make_phantom("head", size=128),
                "scene": _scene("head", 30, 20, "parallel", 128),
                "arch": teramac,
                "projection": "parallel",
            }
        )
        cube4_p8 = dataclasses.replace(cube4, name="cube4-P8", pipelines=8)
        for fname, path, volume, preset in _real_volumes():
            views = [("parallel", 30, 20, 128), ("parallel", 0, 0, 128)]
            views += [("perspective", -35, 10, 128), ("perspective", -35, 10, 256)]
            for arch in (cube4, cube4_p8):
                for projection, az, el, image in views:
                    scene = _scene(path, az, el, projection, image, preset=preset)
                    out.append(
                        {
                            "name": f"{fname} {projection} {az},{el} img{image} P{arch.pipelines}",
                            "volume": volume,
                            "scene": scene,
                            "arch": arch,
                            "projection": projection,
                        }
                    )
    out += _volumepro_cases(quick)
    out += _skipping_cases(quick)
    return out


def _with(scene: Scene, ert: float) -> Scene:
    return scene.replace(render=dataclasses.replace(scene.render, early_termination=ert))


#: Early ray termination threshold and space leaping: off/on, the four combinations.
SKIPPING = [(1.0, False), (0.95, False), (1.0, True), (0.95, True)]


def _skipping_cases(quick: bool) -> list[dict[str, Any]]:
    """VolumePro 1000 and VIZARD II: early ray termination and space leaping off and on,
    parallel and perspective, on the phantoms and the real CT and MR."""
    out = []
    plans = [
        ("volumepro1000", [("head", 40), ("ball", 40), ("marschner-lobb", 41)], 128),
        ("vizard2", [("head", 32), ("ball", 32), ("marschner-lobb", 33)], 48),
    ]
    for name, phantoms, real_image in plans:
        base = resolve_arch(name)
        views = [("parallel", 0, 0), ("parallel", 30, 20), ("parallel", 150, -30)]
        views += [("perspective", -35, 10), ("perspective", 20, 15)]
        for phantom, n in phantoms:
            volume = make_phantom(phantom, size=n)
            for ert, leaping in SKIPPING:
                arch = dataclasses.replace(base, space_leaping=leaping)
                for projection, az, el in views:
                    scene = _scene(phantom, az, el, projection, n, preset="auto", zoom=1.0)
                    out.append(
                        {
                            "name": f"{phantom}{n} {projection} {az},{el} "
                            f"ert{ert:g} leap{int(leaping)} {name}",
                            "volume": volume,
                            "scene": _with(scene, ert),
                            "arch": arch,
                            "projection": projection,
                        }
                    )
        if quick:
            continue
        for fname, path, volume, preset in _real_volumes():
            for ert, leaping in SKIPPING:
                arch = dataclasses.replace(base, space_leaping=leaping)
                for projection, az, el in [("parallel", 30, 20), ("perspective", -35, 10)]:
                    scene = _scene(path, az, el, projection, real_image, preset=preset)
                    out.append(
                        {
                            "name": f"{fname} {projection} {az},{el} img{real_image} "
                            f"ert{ert:g} leap{int(leaping)} {name}",
                            "volume": volume,
                            "scene": _with(scene, ert),
                            "arch": arch,
                            "projection": projection,
                        }
                    )
    return out


def _volumepro_cases(quick: bool) -> list[dict[str, Any]]:
    """VolumePro 500 and EM-Cube (parallel only), with z-supersampling on VolumePro 500."""
    out = []
    phantoms = [("head", 32), ("ball", 32), ("marschner-lobb", 32)]
    if not quick:
        phantoms.append(("head", 64))
    for name in ("volumepro500", "em-cube"):
        arch = resolve_arch(name)
        for phantom, n in phantoms:
            volume = make_phantom(phantom, size=n)
            for az, el in [(0, 0), (30, 20), (150, -30), (90, 45)]:
                out.append(
                    {
                        "name": f"{phantom}{n} parallel {az},{el} {name}",
                        "volume": volume,
                        "scene": _scene(phantom, az, el, "parallel", n),
                        "arch": arch,
                        "projection": "parallel",
                    }
                )
    vp500 = resolve_arch("volumepro500")
    for ss in (2.0, 3.0):
        scene = _scene("head", 30, 20, "parallel", 48)
        scene = scene.replace(render=dataclasses.replace(scene.render, supersampling=ss))
        out.append(
            {
                "name": f"head48 parallel 30,20 supersampling {ss:g} volumepro500",
                "volume": make_phantom("head", size=48),
                "scene": scene,
                "arch": vp500,
                "projection": "parallel",
            }
        )
    for width, overhead in [(8, 0), (6, 50), (16, 200)]:
        sectioned = dataclasses.replace(
            vp500, section_width=width, section_overhead_cycles=overhead
        )
        for az, el in [(30, 20), (150, -30)]:
            out.append(
                {
                    "name": f"head48 parallel {az},{el} sections {width} (+{overhead})",
                    "volume": make_phantom("head", size=48),
                    "scene": _scene("head", az, el, "parallel", 48),
                    "arch": sectioned,
                    "projection": "parallel",
                }
            )
    if not quick:
        for fname, path, volume, preset in _real_volumes():
            for az, el in [(30, 20), (100, 10)]:
                out.append(
                    {
                        "name": f"{fname} parallel {az},{el} img128 volumepro500",
                        "volume": volume,
                        "scene": _scene(path, az, el, "parallel", 128, preset=preset),
                        "arch": vp500,
                        "projection": "parallel",
                    }
                )
    return out


def measure(case: dict[str, Any]) -> dict[str, Any]:
    """Cycle-rung cycles, transaction cycles and the relative error of one case."""
    scene, volume, arch = case["scene"], case["volume"], case["arch"]
    frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
    # Machines that read the frame (beam skipping, block cache) take the functional
    # rung's termination steps, as the transaction rung hands them over.
    stopped = None
    if arch.order == "ray" or arch.early_termination or arch.space_leaping:
        stopped = render_functional(frame).stopped
    txn = transaction_timing(frame, stopped=stopped)
    c = txn.counters
    row = {
        "case": case["name"],
        "arch": arch.name,
        "pipelines": arch.pipelines,
        "projection": case["projection"],
        "volume": list(volume.shape),
        "comparison": transaction_family(arch),
        "transaction_cycles": txn.cycles,
        "timing_model_seconds": c["transaction.timing_seconds"],
    }
    start = time.perf_counter()
    try:
        cycle = render_cycle(frame)
    except NotAvailableError as exc:  # no cycle rung for this machine in this tree
        return _with_independence(
            {
                **row,
                "cycle_cycles": None,
                "error": None,
                "note": f"not yet compared: {exc.message}",
            }
        )
    return _with_independence(
        {
            **row,
            "cycle_cycles": cycle.cycles,
            "error": (txn.cycles - cycle.cycles) / cycle.cycles,
            "cycle_seconds": time.perf_counter() - start,
            # None where the model has no events (VIZARD II's packet model: closed form).
            "events": c.get("transaction.events"),
            "granularity": c.get("transaction.granularity"),
            "stretch_cycles": c.get("pipelines.stretch_cycles"),
            "pipeline_stall_cycles": c.get("pipelines.stall_cycles"),
            "memory_stall_cycles": (
                c.get("memory.stall_cycles"),
                cycle.counters.get("memory.stall_cycles"),
            ),
        }
    )


def _with_independence(row: dict[str, Any]) -> dict[str, Any]:
    """``row`` with its comparison's verdict (``independence``) and the error as the
    table shows it (``error_shown``: a consistency check names the shared code)."""
    comparison = TRANSACTION_VS_CYCLE[row["comparison"]]
    return {
        **row,
        "independence": comparison.verdict,
        "error_shown": shown_error(comparison, row["error"]),
    }


def run(
    quick: bool = False, log=print, note: str | None = None, only: str | None = None
) -> dict[str, Any]:
    """Measure every case (or those whose name contains ``only``); summarise the worst
    error per architecture and projection."""
    rows = []
    for case in cases(quick):
        if only is not None and only not in case["name"]:
            continue
        row = measure(case)
        rows.append(row)
        err = row["error_shown"]
        if row["error"] is None:
            err = "not yet compared"
        elif row["independence"] == SHARED_CODE:
            err = f"{100 * row['error']:+7.3f}% {err}"
        log(f"{row['case']:<52} {row['cycle_cycles']!s:>9} {row['transaction_cycles']:>9} {err}")
    return _summary(
        {
            "schema": 1,
            "benchmark": "transaction-error",
            "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "machine": machine_info(),
            "contract": CONTRACT,
            "note": note,
            "cases": rows,
        }
    )


def _summary(report: dict[str, Any]) -> dict[str, Any]:
    """The report's summary from its ``cases``: the contract, the worst error per
    architecture and view (with each one's independence), the comparisons' details, and
    the largest error of the comparisons that are not shared code."""
    rows = report["cases"]
    compared = [r for r in rows if r["error"] is not None]
    measured = [r for r in compared if r["independence"] != SHARED_CODE]
    worst: dict[str, Any] = {}
    for row in compared:
        key = f"{row['arch']} {row['projection']}"
        if key not in worst or abs(row["error"]) > abs(worst[key]["error"]):
            worst[key] = {
                "case": row["case"],
                "error": row["error"],
                "independence": row["independence"],
                "error_shown": row["error_shown"],
            }
    used = sorted({r["comparison"] for r in rows}, key=list(TRANSACTION_VS_CYCLE).index)
    summary = {
        "within_contract": all(abs(r["error"]) <= CONTRACT for r in compared),
        "max_abs_error": max(abs(r["error"]) for r in compared),
        "max_abs_error_not_shared": max((abs(r["error"]) for r in measured), default=None),
        "not_yet_compared": sorted({r["arch"] for r in rows if r["error"] is None}),
        "worst": worst,
        "independence": {k: TRANSACTION_VS_CYCLE[k].as_dict() for k in used},
        "real_volumes": sorted({r["case"].split()[0] for r in rows if ".nrrd" in r["case"]}),
    }
    head = {k: v for k, v in report.items() if k not in summary and k != "cases"}
    return {**head, **summary, "cases": rows}


def annotate(report: dict[str, Any], archs: dict[str, Any] | None = None) -> dict[str, Any]:
    """An existing report with the independence columns added from its numbers (no case
    is re-measured): each case's comparison from its architecture (``archs``: case name
    to :class:`~hwsim.spec.arch.ArchConfig`, default the cases of this script), its verdict and
    the error as shown, and the summary recomputed."""
    if archs is None:
        archs = {c["name"]: c["arch"] for c in cases(quick=False)}
    rows = []
    for row in report["cases"]:
        if row["case"] not in archs:
            raise KeyError(f"case {row['case']!r} is not one of this script's cases")
        row = {**row, "comparison": transaction_family(archs[row["case"]])}
        rows.append(_with_independence(row))
    return _summary({**report, "cases": rows})


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small phantoms only")
    parser.add_argument("--out", type=Path, default=None, help="JSON report path")
    parser.add_argument("--note", default=None, help="recorded in the report (e.g. the tree)")
    parser.add_argument(
        "--only", default=None, help="measure only the cases whose name contains this text"
    )
    parser.add_argument(
        "--annotate",
        type=Path,
        default=None,
        help="add the independence columns to this existing report (rewritten in place "
        "unless --out is given); nothing is re-measured",
    )
    args = parser.parse_args(argv)
    if args.annotate is not None:
        report = annotate(json.loads(args.annotate.read_text()))
        write_report(report, args.out or args.annotate)
        return 0
    report = run(args.quick, note=args.note, only=args.only)
    print(f"max |error| {100 * report['max_abs_error']:.3f}% (contract {100 * CONTRACT:g}%)")
    measured = report["max_abs_error_not_shared"]
    if measured is not None:
        print(f"max |error| of the comparisons not sharing their timing code {100 * measured:.3f}%")
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
