"""``hwsim trade``: the fidelity-ladder trade, or ``--widths`` for the bit-width trade."""

from __future__ import annotations

import argparse
from typing import Any

from hwsim.core.errors import InputError
from hwsim.studies.trade.table import format_ladder

__all__ = ["trade_command", "plan_trade"]


def plan_trade(volumes: list[str], archs: list[str], widths: bool, out: Any) -> None:
    """Check every file a trade writes in ``out`` against its inputs before any render:
    the machines are loaded first, so each file they read (an arch file, the technology
    it names) is an input too (:func:`hwsim.core.paths.recording_reads`).  The command
    line and :func:`hwsim.api.trade` both plan here."""
    from hwsim.core.paths import in_folder, plan_outputs, recording_reads
    from hwsim.run.fidelity import resolve_arch
    from hwsim.studies.trade.ladder import ladder_paths
    from hwsim.studies.trade.widths import width_paths

    with recording_reads():
        for name in archs:
            resolve_arch(name)
        files = (width_paths if widths else ladder_paths)(out).values()
        inputs = [*(("--volume", v) for v in volumes), *(("--arch", a) for a in archs)]
        plan_outputs(inputs, in_folder("--out", out, files))


def trade_command(args: argparse.Namespace, progress_bar: Any) -> int:
    """Run the trade ``args`` asks for, write its files and print its table."""
    if not 8 <= args.image <= 1024:
        raise InputError(f"{args.image} is out of range", key="--image", allowed="8 .. 1024")
    plan_trade(args.volume, args.arch, args.widths, args.out)  # before any render
    if args.widths:
        return _widths(args, progress_bar)
    from hwsim.studies.trade.ladder import ladder_cases, ladder_trade, write_ladder_trade

    if not 8 <= args.size <= 512:
        raise InputError(f"{args.size} is out of range", key="--size", allowed="8 .. 512")
    rungs = [r.strip() for r in args.rungs.split(",")] if args.rungs else None
    cases = ladder_cases(args.volume, args.image, args.size)
    with progress_bar(args.quiet, "trade") as progress:
        rows = ladder_trade(cases, args.arch or None, rungs, progress=progress, extend=args.extend)
    paths = write_ladder_trade(rows, args.out)
    if not args.quiet:
        print(format_ladder(rows, rows.not_run))
        names = ", ".join(paths[k].name for k in ("json", "md", "png"))
        print(f"wrote {paths['csv']}, {names}")
    return 0


def _widths(args: argparse.Namespace, progress_bar: Any) -> int:
    from hwsim.run.fidelity import resolve_arch
    from hwsim.studies.trade.widths import default_cases, width_trade, write_width_trade

    if len(args.arch) > 1:
        raise InputError("--widths measures one machine", key="--arch", allowed="one NAME|FILE")
    arch = resolve_arch(args.arch[0] if args.arch else "volumepro500")
    cases = default_cases(args.volume, args.image)
    with progress_bar(args.quiet, "widths") as progress:
        rows = width_trade(cases, arch, progress=progress)
    paths = write_width_trade(rows, args.out)
    if not args.quiet:
        print(f"{'knob':<26} {'value':>6} " + " ".join(f"{c.label[:14]:>14}" for c in cases))
        for knob_value in dict.fromkeys((r["knob"], r["value"]) for r in rows):
            cells = [r["psnr_db"] for r in rows if (r["knob"], r["value"]) == knob_value]
            print(
                f"{knob_value[0]:<26} {knob_value[1]:>6} "
                + " ".join(f"{c:>11.1f} dB" for c in cells)
            )
        print(f"wrote {paths['csv']}, {paths['json'].name}, {paths['png'].name}")
    return 0
