"""The ``hwsim rtl`` command: argument parser and runner (hooked into hwsim/cli/commands.py)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hwsim.core.errors import InputError

__all__ = ["add_parser", "run", "run_fpga"]


def add_parser(sub):
    """Add ``rtl build [UNIT|all|top] --out DIR [--set UNIT.KEY=VALUE ...]``; returns the
    ``rtl`` actions (hwsim/cli/commands.py adds ``rtl diff``, which needs the cycle rung)."""
    from rtl.build import UNITS

    r = sub.add_parser("rtl", help="RTL units' Verilog and synthesis stats; diff against cycle")
    actions = r.add_subparsers(dest="rtl_command", metavar="build|fpga|diff", required=True)
    b = actions.add_parser("build", help="write DIR/<unit>.v and DIR/synth.json")
    b.add_argument(
        "unit",
        nargs="?",
        default="all",
        metavar="UNIT|all",
        help=f"one of {', '.join(UNITS)}, all (default: every unit), or top (the Cube-4 "
        "pipeline top: --set top.pipelines=4 top.max_axis=16 top.voxel_bits=12)",
    )
    b.add_argument(
        "--out", metavar="DIR", required=True, help="writes DIR/<unit>.v and DIR/synth.json"
    )
    b.add_argument(
        "--set",
        metavar="UNIT.KEY=VALUE",
        action="append",
        default=[],
        help="a width or parameter of a unit, e.g. interp.weight_bits=6 (repeatable)",
    )
    b.add_argument("--no-synth", action="store_true", help="Verilog only, no Yosys statistics")
    b.add_argument(
        "--abc", action="store_true", help="map gates with ABC (slow on the gradient unit: minutes)"
    )
    b.add_argument("--quiet", action="store_true", help="no progress bar or per-unit lines")
    _add_fpga_parser(actions)
    return actions


def _add_fpga_parser(actions) -> None:
    from rtl.build import UNITS
    from rtl.fpga import CUBE4_MAX_AXIS, CUBE4_PIPELINES, DEFAULT_DEVICE

    f = actions.add_parser(
        "fpga", help="synthesise, place and route on an ECP5 FPGA (Yosys, nextpnr): fpga.json"
    )
    f.add_argument(
        "target",
        metavar="UNIT|top|cube4",
        help=f"one of {', '.join(UNITS)}; top (--set top.pipelines=N ...); cube4 (the "
        f"top that fits an LFE5U-85F: {CUBE4_PIPELINES} pipeline, max_axis "
        f"{CUBE4_MAX_AXIS}, 12-bit voxels; --set top.KEY=VALUE changes them)",
    )
    f.add_argument(
        "--device", default=DEFAULT_DEVICE, metavar="PART", help="ECP5 part (%(default)s)"
    )
    f.add_argument(
        "--out", metavar="DIR", required=True, help="writes DIR/fpga.json, the Verilog and logs"
    )
    f.add_argument(
        "--set", metavar="UNIT.KEY=VALUE", action="append", default=[], help="as rtl build"
    )
    f.add_argument(
        "--arch",
        metavar="NAME|FILE.toml",
        default="cube4",
        help="the machine whose clock is nextpnr's target and the comparison (cube4)",
    )
    f.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def run(args: argparse.Namespace, progress=None) -> int:
    """Build the requested units; print one line per unit."""
    from hwsim.core.paths import in_folder, plan_outputs
    from rtl.build import TARGETS, UNITS, build, parse_settings

    if args.unit != "all" and args.unit not in TARGETS:
        raise InputError(
            f"unknown unit {args.unit!r}", key="UNIT", allowed="all, " + ", ".join(TARGETS)
        )
    units = list(UNITS) if args.unit == "all" else [args.unit]
    settings = parse_settings(args.set)
    for unit in settings:
        if unit not in units:
            raise InputError(
                f"--set names {unit}, which is not being built",
                source="--set",
                key=unit,
                allowed=", ".join(units),
            )
    out = Path(args.out)
    files = [out / f"{unit}.v" for unit in units] + [out / "synth.json"] * (not args.no_synth)
    plan_outputs([], in_folder("--out", out, files))  # every file, before any build
    report = build(units, out, settings, synth=not args.no_synth, abc=args.abc, progress=progress)
    if not args.quiet:
        for unit, entry in report["units"].items():
            stats = (
                f"{entry['cells']:>7} cells {entry['flip_flops']:>5} flip-flops "
                f"{entry['memory_bits']:>8} SRAM bits"
                if "cells" in entry
                else ""
            )
            print(f"{unit:<10} latency {entry['latency']}  {stats}")
        print(f"wrote {out}/" + ("synth.json and " if not args.no_synth else "") + "<unit>.v")
    return 0


def run_fpga(args: argparse.Namespace, arch, progress=None, what_if=None) -> int:
    """Place and route ``args.target`` on ``args.device``; write ``DIR/fpga.json`` (and the
    Verilog and logs beside it).  ``arch``: the machine compared with (its clock is
    nextpnr's target); ``what_if(record, arch)``: extra keys for the record (the caller's
    frame-rate what-if of the top)."""
    from hwsim.core.paths import in_folder, plan_outputs, write_text_atomic
    from rtl.build import UNITS, parse_settings
    from rtl.fpga import (
        CUBE4_MAX_AXIS,
        CUBE4_PIPELINES,
        LOGS,
        parse_device,
        place_and_route,
        tool_versions,
    )

    targets = (*UNITS, "top", "cube4")
    if args.target not in targets:
        raise InputError(
            f"unknown target {args.target!r}", key="TARGET", allowed=", ".join(targets)
        )
    device = parse_device(args.device)
    settings = parse_settings(args.set)
    unit = "top" if args.target == "cube4" else args.target
    if set(settings) - {unit}:
        raise InputError(
            f"--set names {', '.join(sorted(set(settings) - {unit}))}, not {args.target}",
            source="--set",
            allowed=f"{unit}.KEY=VALUE",
        )
    own = settings.get(unit, {})
    if args.target == "cube4":
        own = {"pipelines": CUBE4_PIPELINES, "max_axis": CUBE4_MAX_AXIS, **own}
    out = Path(args.out)
    files = [out / f"{args.target}.v", out / "fpga.json", *(out / log for log in LOGS)]
    plan_outputs([("--arch", args.arch)], in_folder("--out", out, files))
    versions = tool_versions()  # a missing tool: one line before any work
    clock_mhz = arch.clock_hz / 1e6
    record = place_and_route(args.target, own, device, clock_mhz, out, progress)
    record.update(machine=arch.name, machine_clock_mhz=clock_mhz, tools=versions, logs=list(LOGS))
    if what_if is not None:
        record.update(what_if(record, arch))
    write_text_atomic(out / "fpga.json", json.dumps(record, indent=1, sort_keys=True) + "\n")
    if not args.quiet:
        fmax = record["fmax_mhz"]
        print(
            f"{args.target} on {device.part}: fmax {fmax:.1f} MHz (machine {arch.name} "
            f"{clock_mhz:g} MHz), {record['luts']} LUTs, {record['ffs']} FFs, "
            f"{record['dsps']} DSPs, {record['brams']} BRAMs"
            if fmax is not None
            else f"{args.target}: no clocked path; {record['luts']} LUTs"
        )
        print(f"wrote {out}/fpga.json")
    return 0
