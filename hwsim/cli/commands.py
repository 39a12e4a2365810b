"""The ``hwsim`` command: parse, load, call the library, print a short summary.

Exit status: 0 on success, 2 for bad input (one line on stderr naming the file, key
and allowed range), 1 for an internal fault (``HWSIM_DEBUG=1`` shows the traceback).
The command-line contract is design section 9; docs/cli.md documents it.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from hwsim.cli.energy import cmd_energy
from hwsim.cli.parser import build_parser
from hwsim.cli.progress import progress_bar as _progress_bar
from hwsim.cli.render import DEFAULT_RENDER_OUT, cmd_convert, cmd_render
from hwsim.cli.warm import cmd_warm
from hwsim.core import env, interrupt
from hwsim.core.errors import HwsimError, InputError
from hwsim.core.logs import configure_logging
from hwsim.spec.overrides import apply_overrides
from hwsim.studies.bench import TABLE_GOALS

__all__ = ["main", "build_parser", "DEFAULT_RENDER_OUT"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status."""
    with interrupt.handling_sigint():  # Ctrl-C: exit 130 in seconds, frame threads too
        try:
            args = build_parser().parse_args(argv)  # imports most of hwsim: seconds
        except KeyboardInterrupt:
            interrupt.say()
            return interrupt.EXIT_STATUS
        configure_logging(args.verbose)
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the command of ``args``; its errors as one line and an exit status."""
    from hwsim.core.paths import recording_reads

    try:
        env.validate()  # every HWSIM_* variable, before any work (hwsim.core.env)
        with recording_reads():  # every file read is an input no output may replace
            if getattr(args, "max_memory", None) is not None:
                from hwsim.core.budget import memory_budget_of, parse_size

                with memory_budget_of(parse_size(args.max_memory, key="--max-memory")):
                    return _COMMANDS[args.command](args)
            return _COMMANDS[args.command](args)
    except InputError as exc:
        print(f"hwsim: error: {exc}", file=sys.stderr)
        return 2
    except HwsimError as exc:
        print(f"hwsim: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # stdout closed early (`hwsim archs --features | head`)
        sys.stdout = open(os.devnull, "w")
        return 0
    except KeyboardInterrupt:
        from hwsim.core.threads import join_pools

        join_pools()  # each frame thread stops at its next step
        interrupt.say()
        return interrupt.EXIT_STATUS
    except Exception as exc:  # an internal fault: say so in one line, keep the exit code 1
        from hwsim.core.paths import os_problem

        if (problem := os_problem(exc)) is not None:  # any OSError: a path the user gave
            print(f"hwsim: error: {problem}", file=sys.stderr)
            return 2
        if env.value("HWSIM_DEBUG"):
            raise
        print(
            f"hwsim: internal error: {type(exc).__name__}: {exc} "
            "(set HWSIM_DEBUG=1 for the traceback)",
            file=sys.stderr,
        )
        return 1


# ---------------------------------------------------------------------------- commands


def _cmd_scenes(args: argparse.Namespace) -> int:
    from hwsim.spec.scene import DEFAULT_SCENE, builtin_scenes

    for name, text in builtin_scenes().items():
        mark = " (default)" if name == DEFAULT_SCENE else ""
        print(f"{name:<20} {text}{mark}")
    return 0


def _cmd_phantoms(args: argparse.Namespace) -> int:
    from hwsim.volumes import PHANTOMS

    for name, info in PHANTOMS.items():
        print(f"{name:<16} {info}")
    return 0


def _cmd_archs(args: argparse.Namespace) -> int:
    from hwsim.run.fidelity import builtin_archs, machine_rungs

    if args.features:
        from hwsim.spec.machine_features import feature_rows

        for name, arch in builtin_archs().items():
            print(name)
            for feature, has, source in feature_rows(arch):
                print(f"  {feature:<21} {has:<34} {source}")
        return 0
    from hwsim.energy import load_technology, units_below_clock
    from hwsim.energy.synth import fmax_basis

    print(f"{'name':<15} {'order':<15} {'P':>3} {'clock':>10} {'peak':>12}  {'node':<8} rungs")
    flags, basis = [], ""
    for name, arch in builtin_archs().items():
        rungs = " ".join(machine_rungs(arch))
        print(
            f"{name:<15} {arch.order:<15} {arch.pipelines:>3} {arch.clock_hz / 1e6:>6.2f} MHz "
            f"{arch.peak_samples_per_second / 1e6:>7.0f} MS/s  {arch.technology:<8} {rungs}"
        )
        slow = units_below_clock(arch)
        if slow:
            units = ", ".join(f"{u} ~{f / 1e6:.0f} MHz" for u, f in slow)
            clock = f"{arch.clock_hz / 1e6:.0f} MHz"
            flags.append(f"  {name}: estimated below its {clock} clock: {units}")
            basis = fmax_basis(load_technology(arch.technology))
    if flags:
        print(f"units whose synthesised RTL is estimated slower than the clock ({basis}; "
              "docs/energy.md):")  # fmt: skip
        print("\n".join(flags))
    _print_routed_fmax()
    return 0


def _print_routed_fmax() -> None:
    """The third measure of each unit's clock: placed and routed on an ECP5."""
    from hwsim.energy.fpga import fpga_measured

    data = fpga_measured()
    units = data.get("units", {})
    routed = [f"{u} {e['fmax_mhz']:.0f} MHz" for u, e in units.items() if e.get("fmax_mhz")]
    if routed:
        print(f"each unit's RTL placed and routed on an {data['device']} (hwsim rtl fpga; "
              "docs/energy.md): " + ", ".join(routed))  # fmt: skip


def _cmd_trade(args: argparse.Namespace) -> int:
    from hwsim.studies.trade.command import trade_command

    return trade_command(args, _progress_bar)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from hwsim.studies.sweep.command import sweep_command

    return sweep_command(args, _progress_bar)


def _cmd_figures(args: argparse.Namespace) -> int:
    from hwsim.studies.figures_tables import figures_command

    return figures_command(args, _progress_bar)


def _cmd_report(args: argparse.Namespace) -> int:
    from hwsim.core.paths import display_path, in_folder, plan_outputs
    from hwsim.report.report import report_inputs, report_paths, write_report

    outputs = in_folder("--out", args.out, report_paths(args.out, args.runs).values())
    plan_outputs(report_inputs(args.runs), outputs)  # never onto a file it reads
    paths = write_report(args.runs, args.out)
    if not args.quiet:
        print(f"wrote {display_path(paths['md'])} and {paths['html'].name}")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from hwsim.core.paths import display_text, in_folder, plan_outputs, write_text_atomic
    from hwsim.run.fidelity import resolve_arch
    from hwsim.studies.bench import failures, format_bench, run_bench

    for flag, value, lo, hi in (
        ("--size", args.size, 8, 512),
        ("--image", args.image, 8, 1024),
        ("--repeats", args.repeats, 1, 100),
        ("--rtl-size", args.rtl_size, 4, 128),
    ):
        if not lo <= value <= hi:
            raise InputError(f"{value} is out of range", key=flag, allowed=f"{lo} .. {hi}")
    for n in (*args.table_sizes, args.memory_size):
        if not 8 <= n <= 1024:
            raise InputError(
                f"{n} is out of range", key="--table-sizes/--memory-size", allowed="8 .. 1024"
            )
    rows = args.rows
    if rows == ["none"]:
        rows = []
    elif rows is not None:
        for row in rows:
            if row not in TABLE_GOALS:
                allowed = ", ".join(TABLE_GOALS) + ", none"
                raise InputError(f"no row {row!r}", key="--rows", allowed=allowed)
    out = Path(args.out)
    resolve_arch(args.arch)  # first: each file it reads is an input of the plan
    plan_outputs([("--arch", args.arch)], in_folder("--out", out, [out / "bench.json"]))

    def save(report: dict) -> None:  # its notes' paths relative (hwsim.core.paths)
        write_text_atomic(out / "bench.json", display_text(json.dumps(report, indent=2)) + "\n")

    def log(message: str) -> None:  # above the progress bar, not through it
        if not args.quiet:
            from tqdm import tqdm

            tqdm.write(message, file=sys.stderr)

    with _progress_bar(args.quiet, "bench") as progress:
        report = run_bench(
            args.size,
            args.image,
            args.arch,
            args.repeats,
            vtk=not args.no_vtk,
            sweep=not args.no_sweep,
            rows=rows,
            table_sizes=args.table_sizes,
            memory_size=args.memory_size,
            rtl_size=args.rtl_size,
            log=log,
            progress=progress or (lambda done, total, what: None),
            checkpoint=save,
        )
    failed = failures(report)
    if not args.quiet:
        print(format_bench(report))
        print(f"wrote {out / 'bench.json'}")
    if failed:
        print(f"hwsim: bench: {', '.join(failed)} failed (see bench.json)", file=sys.stderr)
    return 1 if failed else 0


def _cmd_rtl(args: argparse.Namespace) -> int:
    if args.rtl_command == "diff":
        return _rtl_diff(args)
    if args.rtl_command == "fpga":
        return _rtl_fpga(args)
    from rtl.cli import run

    with _progress_bar(args.quiet, "rtl build") as progress:
        return run(args, progress)


def _rtl_fpga(args: argparse.Namespace) -> int:
    """Place and route on an ECP5; a top's record gets the frame-rate what-if."""
    from hwsim.run.fidelity import resolve_arch
    from hwsim.studies.fpga import what_if
    from rtl.cli import run_fpga

    arch = resolve_arch(args.arch)
    with _progress_bar(args.quiet, "rtl fpga") as progress:
        return run_fpga(args, arch, progress, what_if)


def _rtl_diff(args: argparse.Namespace) -> int:
    """Exit 0 when the rungs agree on every event, 1 where they differ."""
    from hwsim.spec.scene import load_scene
    from hwsim.studies.rtl_diff import rtl_diff

    scene = apply_overrides(load_scene(args.scene), args)
    report = rtl_diff(scene, arch=args.arch, simulator=args.simulator)
    if not args.quiet:
        for line in report.lines():
            print(line)
    return 0 if report.identical else 1


_COMMANDS = {
    "render": cmd_render,
    "convert": cmd_convert,
    "scenes": _cmd_scenes,
    "phantoms": _cmd_phantoms,
    "archs": _cmd_archs,
    "trade": _cmd_trade,
    "sweep": _cmd_sweep,
    "report": _cmd_report,
    "figures": _cmd_figures,
    "bench": _cmd_bench,
    "energy": cmd_energy,
    "rtl": _cmd_rtl,
    "warm": cmd_warm,
}


if __name__ == "__main__":
    sys.exit(main())
