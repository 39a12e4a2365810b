"""The ``hwsim`` command line's parser: one builder per subcommand, the options they share.

The commands themselves run in :mod:`hwsim.cli.commands` (design section 9; docs/cli.md).
"""

from __future__ import annotations

import argparse

from hwsim.cli.energy import add_energy_parser
from hwsim.cli.render import DEFAULT_RENDER_OUT
from hwsim.cli.scene import add_scene_options
from hwsim.cli.warm import add_warm_parser
from hwsim.studies.bench import TABLE_GOALS

__all__ = ["build_parser"]


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
