"""``hwsim energy``: one frame's energy priced two ways, the technology tables (what every
other command reports) and Accelergy's component library beside them, per unit, per
memory and per frame (:mod:`hwsim.energy.accelergy`; docs/energy.md).
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from hwsim.cli.progress import progress_bar
from hwsim.cli.scene import add_scene_options

__all__ = ["add_energy_parser", "cmd_energy"]

#: The second price: the one library hwsim knows (the flag says which it is).
LIBRARIES = ("accelergy",)


def add_energy_parser(sub) -> None:
    e = sub.add_parser(
        "energy", help="a frame's energy per unit: the technology tables beside Accelergy's"
    )
    add_scene_options(e)
    e.add_argument(
        "--arch",
        metavar="NAME|FILE.toml",
        default="volumepro500",
        help="machine: a built-in name (hwsim archs) or a file (default: volumepro500)",
    )
    e.add_argument(
        "--fidelity",
        choices=("cycle", "transaction"),
        default="cycle",
        help="the rung that counts the frame's actions (default: cycle)",
    )
    e.add_argument(
        "--technology",
        metavar="NAME|FILE.toml",
        help="price in this technology (default: the machine's era node); the library "
        "prices at its node",
    )
    e.add_argument(
        "--library",
        choices=LIBRARIES,
        default="accelergy",
        help="the second price: Accelergy's component library, hwcomponents (default)",
    )
    e.add_argument("--out", metavar="FILE.json", help="also write the band as JSON here")
    e.add_argument("--quiet", action="store_true", help="no progress bar or table")


def cmd_energy(args: argparse.Namespace) -> int:
    """Render the frame at ``--fidelity``, price it both ways, print the band."""
    from hwsim.api import naming_flags, render
    from hwsim.core.paths import FILE, plan_outputs, write_text_atomic
    from hwsim.energy.accelergy import band_of_run
    from hwsim.run.fidelity import resolve_arch
    from hwsim.run.output import scene_inputs
    from hwsim.spec.overrides import apply_overrides
    from hwsim.spec.scene import load_scene

    scene = apply_overrides(load_scene(args.scene), args)
    arch = resolve_arch(args.arch)
    plan_outputs([*scene_inputs(scene), ("--arch", args.arch)], [("--out", args.out, FILE)])
    with naming_flags(), progress_bar(args.quiet, "render") as progress:
        run = render(scene, args.fidelity, args.arch, progress=progress, technology=args.technology)
    band = band_of_run(run.render_run, arch, args.technology)
    if args.out:
        write_text_atomic(args.out, json.dumps(band, indent=1) + "\n")
    if not args.quiet:
        print(_table(arch.name, band))
    return 0


def _table(name: str, band: dict[str, Any]) -> str:
    """The band as a few aligned lines: joules both ways and library / tables."""
    tech, lib = band["technology"], band["library"]
    rows = [
        f"{name}, {tech['name']} ({tech['node_nm']:g} nm, {tech['vdd']:g} V): the tables "
        f"vs Accelergy's library (hwcomponents {lib['hwcomponents']}); ratio = library / tables",
        f"{'':22} {'tables J':>11} {'library J':>11} {'ratio':>8}",
    ]
    parts = [*band["units"].items(), *band["memories"].items(), ("frame", band["frame"])]
    for key, row in parts:
        ratio = f"{row['ratio']:8.3g}" if row["ratio"] else f"{'-':>8}"
        rows.append(
            f"{key:22} {row['horowitz_joules']:11.3e} {row['library_joules']:11.3e} {ratio}"
        )
    f = band["frame"]
    rows.append(
        f"outside the band: DRAM activations and refreshes {f['not_priced_joules']:.3e} J "
        f"(no library action), leakage {f['static_joules']:.3e} J"
    )
    return "\n".join(rows)
