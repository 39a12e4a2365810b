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

from hwsim.cli.energy import add_energy_parser, cmd_energy
from hwsim.cli.progress import progress_bar as _progress_bar
from hwsim.cli.render import DEFAULT_RENDER_OUT, cmd_convert, cmd_render
from hwsim.cli.scene import add_scene_options
from hwsim.cli.warm import add_warm_parser, cmd_warm
from hwsim.core import env, interrupt
from hwsim.core.errors import HwsimError, InputError
from hwsim.core.logs import configure_logging
from hwsim.spec.overrides import apply_overrides
from hwsim.studies.bench import TABLE_GOALS

__all__ = ["main", "build_parser", "DEFAULT_RENDER_OUT"]


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage mistake as one line and exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


#: The first line of ``hwsim --help``, for users.
DESCRIPTION = "Simulate volume-rendering hardware: Cube-4, VolumePro, EM-Cube, VIZARD II."
EPILOG = """\
Run 'hwsim COMMAND --help' for a command's options; -v or -vv before or after the
command logs what hwsim and its libraries (Dask, numba, ...) do.
Documentation: README.md (getting started) and docs/cli.md (every command, its outputs
and exit status) in the hwsim source tree; docs/ covers scenes, machines and sweeps."""


def build_parser() -> argparse.ArgumentParser:
    """The ``hwsim`` parser: one subparser per command, ``--verbose`` on each."""
    parser = _Parser(
        prog="hwsim",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=_version())
    sub = parser.add_subparsers(
        title="commands", dest="command", metavar="COMMAND", required=True, parser_class=_Parser
    )
    for add_subparser in _SUBPARSERS:
        add_subparser(sub)
    _add_verbose(parser, default=0)
    return parser


def _add_verbose(parser: argparse.ArgumentParser, default: object) -> None:
    """``-v/--verbose`` on ``parser`` and every subcommand below it (there it keeps the
    top level's count unless given: ``hwsim -v sweep ...`` and ``hwsim sweep ... -v``)."""
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=default,
        help="log more from hwsim and its libraries: -v INFO, -vv DEBUG (default: warnings only)",
    )
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _add_verbose(child, default=argparse.SUPPRESS)


def _add_render_parser(sub) -> None:
    from hwsim.run.fidelity import FIDELITIES, SAMPLINGS

    r = sub.add_parser("render", help="render a scene at a fidelity; writes image + stats.json")
    add_scene_options(r)
    r.add_argument(
        "--arch",
        metavar="NAME|FILE.toml",
        help="machine: a built-in name (hwsim archs) or a file (default: volumepro500 on the "
        "timed rungs; golden: none, or render at its sample positions)",
    )
    r.add_argument(
        "--fidelity",
        choices=FIDELITIES,
        default="golden",
        help="rung of the ladder: float64 reference, bit-exact datapath, memory timing, "
        "clock by clock, or the Verilog itself (default: golden; docs/fidelity.md)",
    )
    r.add_argument(
        "--sampling",
        choices=SAMPLINGS,
        default="ray",
        help="golden sample positions: ideal rays or an architecture's order (default: ray)",
    )
    r.add_argument(
        "--trace", metavar="FILE.vcd", help="cycle/rtl rung: VCD waveform of the hardware"
    )
    r.add_argument(
        "--simulator",
        choices=("verilator", "icarus"),
        help="rtl rung: HDL simulator (default verilator)",
    )
    r.add_argument(
        "--extend",
        action="store_true",
        help="render features the machine never had as a what-if (stats.json: extensions)",
    )
    r.add_argument(
        "--threads",
        type=int,
        metavar="N",
        default=None,
        help="threads per frame (default: every usable core, or HWSIM_THREADS); the image "
        "and cycles do not depend on it",
    )
    r.add_argument(
        "--technology",
        metavar="NAME|FILE.toml",
        help="cycle and transaction rungs: price energy and area in this technology "
        "(cmos45, cmos250, cmos350 or a file; default: the machine's era node)",
    )
    _add_render_cluster_options(r)
    _add_render_output_options(r)


def _add_render_cluster_options(r: argparse.ArgumentParser) -> None:
    """render's split-frame options: a local or remote Dask cluster, cut into bands."""
    r.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="cycle rung, Cube-4 family: split the frame across N worker processes (a "
        "local Dask cluster); the volume is read in parts, the frame bit-identical",
    )
    r.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="cycle rung, Cube-4 family: split the frame across the Dask cluster at "
        "tcp://HOST:PORT",
    )
    r.add_argument(
        "--bands",
        type=int,
        metavar="N",
        help="with --workers/--scheduler: bands of rays the frame is cut into (default: "
        "one per worker)",
    )


def _add_render_output_options(r: argparse.ArgumentParser) -> None:
    """render's options for what is written: timing only, a turntable, the folder."""
    r.add_argument(
        "--timing-only",
        action="store_true",
        help="transaction rung: time the frame without its image (stats.json only)",
    )
    r.add_argument(
        "--frames",
        type=int,
        default=1,
        metavar="N",
        help="a turntable of N frames: frames/*.png, turntable.gif, per-frame wall times",
    )
    r.add_argument(
        "--turn",
        type=float,
        metavar="DEG",
        help="azimuth step between turntable frames (default 360 / N)",
    )
    r.add_argument(
        "--out", metavar="DIR", help=f"output folder (default {DEFAULT_RENDER_OUT}, replaced)"
    )
    _add_max_memory(r)
    r.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def _add_convert_parser(sub) -> None:
    c = sub.add_parser("convert", help="rewrite a volume uncompressed (.nrrd, .npy): read in parts")
    c.add_argument("volume", metavar="IN", help="volume file or DICOM folder")
    c.add_argument("out", metavar="OUT", help="OUT.nrrd (raw, keeps spacing and units) or .npy")
    _add_max_memory(c)


def _add_listing_parsers(sub) -> None:
    """The listings: scenes, phantoms, archs."""
    sub.add_parser("scenes", help="list built-in scenes")
    sub.add_parser("phantoms", help="list built-in phantoms and their parameters")
    a = sub.add_parser("archs", help="list built-in architectures")
    a.add_argument(
        "--features",
        action="store_true",
        help="each machine's declared features and their sources",
    )


def _add_trade_parser(sub) -> None:
    t = sub.add_parser("trade", help="measure the fidelity ladder (speed vs error), or --widths")
    t.add_argument(
        "--widths",
        action="store_true",
        help="bit-width trade: PSNR vs golden as each datapath width shrinks",
    )
    t.add_argument(
        "--extend",
        action="store_true",
        help="also measure scenes outside a machine's features, as what-if rows",
    )
    _add_repeatable(t, "--volume", "PATH", "add a volume file to the scene set")
    _add_repeatable(
        t, "--arch", "NAME|FILE.toml", "machines to measure (default every built-in, "
        "--widths: volumepro500)",
    )  # fmt: skip
    t.add_argument("--rungs", metavar="R,R,...", help="rungs to measure (default: all five)")
    t.add_argument("--image", metavar="N", type=int, default=64, help="square image side (64)")
    t.add_argument("--size", metavar="N", type=int, default=64, help="phantom side in voxels (64)")
    t.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="writes trade.csv/.json/.md/.png (--widths: widths.csv/.json/.png)",
    )
    _add_max_memory(t)
    _add_quiet(t)


def _add_sweep_parser(sub) -> None:
    w = sub.add_parser("sweep", help="design-space sweep on Dask; rows in SQLite")
    w.add_argument("file", metavar="SWEEP.toml", help="sweep file (docs/sweeps.md)")
    where = w.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", metavar="N", type=int, default=2, help="local worker processes (2)"
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="an existing Dask scheduler at tcp://HOST:PORT"
    )
    w.add_argument("--db", metavar="FILE", default="runs.db", help="SQLite file (runs.db)")
    w.add_argument("--out", metavar="DIR", help="also write each run's render folder here")
    w.add_argument("--retry-failed", action="store_true", help="rerun runs recorded as failed")
    _add_max_memory(w)
    _add_quiet(w)


def _add_report_parser(sub) -> None:
    rp = sub.add_parser("report", help="human report of runs: report.md + report.html")
    runs_help = "render, sweep --out or trade folders, or a sweep's runs.db"
    rp.add_argument("runs", metavar="RUN_DIR", nargs="+", help=runs_help)
    rp.add_argument("--out", metavar="DIR", required=True, help="writes report.md and report.html")
    _add_quiet(rp)


def _add_figures_parser(sub) -> None:
    f = sub.add_parser("figures", help="published figures of each machine vs every timing rung")
    _add_repeatable(
        f, "--arch", "NAME|FILE.toml", "machines (default every built-in with [published] figures)"
    )
    f.add_argument("--rungs", metavar="R,R,...", help="timing rungs (default: all four)")
    f.add_argument(
        "--max-size", metavar="N", type=int, default=256, help="skip scenarios above N^3 (256)"
    )
    f.add_argument("--out", metavar="DIR", required=True, help="writes figures.json/.csv/.md")
    _add_max_memory(f)
    _add_quiet(f)


def _add_bench_parser(sub) -> None:
    b = sub.add_parser("bench", help="speed of every rung and the goal ratios, as JSON")
    b.add_argument("--size", metavar="N", type=int, default=64, help="head phantom side (64)")
    b.add_argument("--image", metavar="N", type=int, default=128, help="image side (128)")
    b.add_argument(
        "--arch", metavar="NAME|FILE.toml", default="volumepro500", help="machine (volumepro500)"
    )
    b.add_argument("--repeats", metavar="K", type=int, default=3, help="timed renders per rung (3)")
    b.add_argument(
        "--no-vtk", action="store_true", help="skip every use of VTK (the golden vs VTK rows)"
    )
    b.add_argument(
        "--no-sweep",
        action="store_true",
        help="skip the Dask ratios: the 1 vs 2 worker sweep and split frame",
    )
    _add_bench_table_options(b)
    b.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="writes DIR/bench.json (as each step starts, so a partial run leaves one)",
    )
    b.add_argument("--quiet", action="store_true", help="no progress bar, skip lines or table")


def _add_bench_table_options(b: argparse.ArgumentParser) -> None:
    """bench's speed-table options: which rows, at which volume sides."""
    b.add_argument(
        "--rows",
        metavar="ROW",
        nargs="+",
        default=None,
        help="speed-table rows (default all; 'none' for none): " + ", ".join(TABLE_GOALS),
    )
    b.add_argument(
        "--table-sizes",
        metavar="N",
        type=int,
        nargs="+",
        default=[128, 256],
        help="volume sides of the cycle and timing-only rows (128 256)",
    )
    b.add_argument(
        "--memory-size", metavar="N", type=int, default=512, help="side of the memory row (512)"
    )
    b.add_argument(
        "--rtl-size",
        metavar="N",
        type=int,
        default=64,
        help="head phantom side of the rtl row and cycle_vs_rtl (64; the first run of a size "
        "class builds its Verilator model, minutes)",
    )


def _add_rtl_parsers(sub) -> None:
    """rtl's own subcommands (rtl.cli) and its diff against the cycle rung."""
    from rtl.cli import add_parser as add_rtl_parser

    rtl_actions = add_rtl_parser(sub)
    d = rtl_actions.add_parser(
        "diff",
        help="render a scene at the cycle and rtl rungs; the first clock where they differ",
    )
    add_scene_options(d)
    d.add_argument(
        "--arch",
        metavar="NAME|FILE.toml",
        default="cube4",
        help="a machine of the Cube-4 family, the one the RTL top implements (cube4)",
    )
    d.add_argument(
        "--simulator",
        choices=("verilator", "icarus"),
        default="verilator",
        help="HDL simulator of the rtl rung (verilator)",
    )
    d.add_argument(
        "--quiet", action="store_true", help="print nothing: the exit status says (0 agree)"
    )


# One builder per subcommand, in the order ``hwsim --help`` lists them.
_SUBPARSERS = (
    _add_render_parser,
    _add_convert_parser,
    _add_listing_parsers,
    _add_trade_parser,
    _add_sweep_parser,
    _add_report_parser,
    _add_figures_parser,
    _add_bench_parser,
    add_energy_parser,
    _add_rtl_parsers,
    add_warm_parser,
)


def _add_repeatable(parser: argparse.ArgumentParser, flag: str, metavar: str, what: str) -> None:
    """An option that may be given many times, collected into a list."""
    parser.add_argument(
        flag, metavar=metavar, action="append", default=[], help=f"{what} (repeatable)"
    )


def _add_quiet(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def _add_max_memory(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--max-memory",
        metavar="SIZE",
        help="memory budget per process, e.g. 2G (default: half the available memory)",
    )


def _version() -> str:
    from hwsim import __version__

    return f"hwsim {__version__}"


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
