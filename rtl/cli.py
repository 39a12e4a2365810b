"""The ``hwsim rtl`` command: argument parser and runner (hooked into hwsim/cli/commands.py)."""

from __future__ import annotations

import argparse
from pathlib import Path

from hwsim.core.errors import InputError

__all__ = ["add_parser", "run"]


def add_parser(sub):
    """Add ``rtl build [UNIT|all|top] --out DIR [--set UNIT.KEY=VALUE ...]``; returns the
    ``rtl`` actions (hwsim/cli/commands.py adds ``rtl diff``, which needs the cycle rung)."""
    from rtl.build import UNITS

    r = sub.add_parser("rtl", help="RTL units' Verilog and synthesis stats; diff against cycle")
    actions = r.add_subparsers(dest="rtl_command", metavar="build|diff", required=True)
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
    return actions


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
