"""The Cube-4 top on today's FPGA, as a what-if, and the stored FPGA measurements.

# Ref: rtl/fpga.py (the Yosys + nextpnr-ecp5 flow); shared/docs/reference/architectures.md
#      section 1.1 (Kanus et al., EGGH 1996: Cube-4 on the Teramac, 128^3 in 0.65 s at
#      0.96 MHz); hwsim/studies/figures.py (the dense scenario).

:func:`what_if` prices the routed top's cycles at its routed fmax: the cycle rung renders
the figures' dense scenario (head phantom, one sample per voxel, :func:`figure_scene`) at
the largest volume the top holds (``max_axis``, 128 for the ``cube4`` target: the
Teramac's own 128^3) on the ``cube4`` machine at the top's pipeline count, and the frame
rate is ``fmax / cycles``.  The cycles are the cycle rung's, equal to the rtl rung's on
every cosim scene (the cosim suite checks it), so this is the routed RTL's own frame at
the clock its routed wires allow on an ECP5: a what-if of today's FPGA, not a published
machine.  Beside it, the Teramac prototype's 0.96 MHz at the same cycles, and its
published 0.65 s.

``python -m hwsim.studies.fpga [--units all|none|LIST] [--pipelines 1,N] [--jobs N]``
re-measures every unit and the ``cube4`` top at the pipeline counts given (default
:data:`TOP_PIPELINES`) and merges them into ``hwsim/energy/data/units_fpga.json``, each
run with the command that repeats it and the commit of ``rtl/`` and ``models/units/`` it
was measured on (``+``: with uncommitted changes); tens of minutes on two cores.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["WHAT_IF", "what_if", "refresh"]

WHAT_IF = "what-if: the routed RTL on today's ECP5 at its routed fmax, not a published machine"
#: The ``cube4`` top's pipeline counts :func:`refresh` routes: P = 1, routed on an
#: LFE5U-85F, and P = 2, which Yosys maps to 150 of its 156 multipliers (docs/rtl.md);
#: a run that does not fit is stored with its one-line error.
TOP_PIPELINES = (1, 2)
_DATA = "units_fpga.json"
#: The Teramac's rendered size: the what-if's frame.
TERAMAC_SIZE = 128


def _cycles(pipelines: int, voxel_bits: int, size: int) -> int:
    """The cycle rung's cycles of the dense ``size^3`` scenario on ``cube4`` at P."""
    from hwsim.core.config import flatten_table
    from hwsim.run.fidelity import render, resolve_arch
    from hwsim.studies.figures import figure_scene

    cube4 = resolve_arch("cube4")
    formats = {**flatten_table(cube4.formats), "voxel.bits": voxel_bits}
    machine = dataclasses.replace(cube4, pipelines=pipelines, formats=formats)
    return int(render(figure_scene(size), fidelity="cycle", arch=machine).cycles)


def what_if(record: dict[str, Any], arch) -> dict[str, Any]:
    """``what_if_frame_rate`` (the 128^3 dense frame at the routed fmax) and its basis for
    a routed top (``{}`` for a unit or an unrouted one)."""
    from hwsim.run.fidelity import resolve_arch
    from hwsim.studies.figures import published_figures

    if record["target"] not in ("top", "cube4") or not record.get("fmax_mhz"):
        return {}
    params, fmax_hz = record["params"], record["fmax_mhz"] * 1e6
    pipelines, holds = params["pipelines"], params["max_axis"]
    cycles = _cycles(pipelines, params["voxel_bits"], TERAMAC_SIZE)
    own = _cycles(pipelines, params["voxel_bits"], holds) if holds < TERAMAC_SIZE else cycles
    teramac = resolve_arch("cube4-teramac")
    published = {f.key: f.value for f in published_figures(teramac)}
    return {
        "what_if_frame_rate": fmax_hz / cycles,
        "what_if": {
            "what": WHAT_IF,
            "scene": f"dense head {TERAMAC_SIZE}^3 (the figures' scenario), cycle rung",
            "machine": f"cube4 at P = {pipelines}, {params['voxel_bits']}-bit voxels",
            "cycles": cycles,
            "fmax_mhz": record["fmax_mhz"],
            "seconds": cycles / fmax_hz,
            "holds": (
                f"the routed top holds volumes up to {holds}^3: at {TERAMAC_SIZE}^3 its "
                "compositing buffer grows, so the rate assumes the routed fmax holds there "
                "(an upper bound)"
                if holds < TERAMAC_SIZE
                else f"the routed top holds {TERAMAC_SIZE}^3"
            ),
            "own_frame": {"size": holds, "cycles": own, "frame_rate": fmax_hz / own},
            "teramac_clock_mhz": teramac.clock_hz / 1e6,
            "teramac_frame_rate_same_cycles": teramac.clock_hz / cycles,
            "teramac_published_seconds_128": published.get("seconds_128"),
        },
    }


def _measure(target: str, sets: list[str], device: str, root: Path) -> dict[str, Any]:
    """One ``hwsim rtl fpga`` run in its own process (Ctrl-C reaches it too)."""
    name = target + "".join("-" + s.split("=")[1] for s in sets)
    out = root / name
    args = ["rtl", "fpga", target, "--device", device, *(x for s in sets for x in ("--set", s))]
    cmd = [sys.executable, "-m", "hwsim.cli.commands", *args, "--out", str(out), "--quiet"]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    command = "hwsim " + " ".join(args) + " --out DIR"
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1:], "command": command}
    record = json.loads((out / "fpga.json").read_text())
    record["wall_seconds"] = round(time.perf_counter() - t0, 1)
    record["command"] = command
    return record


def _rtl_commit() -> str | None:
    """The last commit of the RTL and unit models here, ``+`` if the tree differs."""
    repo = Path(__file__).parents[2]
    where = ["--", "rtl", "models/units"]
    log = subprocess.run(
        ["git", "log", "-1", "--format=%h", *where], capture_output=True, text=True, cwd=repo
    )
    status = subprocess.run(
        ["git", "status", "--porcelain", *where], capture_output=True, text=True, cwd=repo
    )
    if log.returncode != 0 or not log.stdout.strip():
        return None
    return log.stdout.strip() + ("+" if status.stdout.strip() else "")


def refresh(
    path: Path,
    device: str,
    jobs: int,
    units: list[str],
    pipelines: list[int],
    rtl_commit: str | None = None,
) -> dict[str, Any]:
    """Route ``units`` and the ``cube4`` top at each of ``pipelines``; merge them into the
    data file at ``path`` (the other entries stay) and write it."""
    runs = [(u, []) for u in units] + [("cube4", [f"top.pipelines={p}"]) for p in pipelines]
    with tempfile.TemporaryDirectory(prefix="hwsim-fpga-") as tmp:
        with ThreadPoolExecutor(max(jobs, 1)) as pool:
            done = list(pool.map(lambda r: _measure(*r, device, Path(tmp)), runs))
    old = json.loads(path.read_text()) if path.is_file() else {}
    commit = rtl_commit or _rtl_commit()
    for record in done:
        record["rtl_commit"] = commit
    out = {
        "schema": 1,
        "what": "every unit and the Cube-4 top placed and routed on an ECP5 (rtl/fpga.py)",
        "command": "python -m hwsim.studies.fpga [--units all] [--pipelines 1,N]",
        "device": device,
        "units": {**old.get("units", {}), **dict(zip(units, done, strict=False))},
        "tops": {
            **old.get("tops", {}),
            **{f"cube4-P{p}": r for p, r in zip(pipelines, done[len(units) :], strict=True)},
        },
    }
    from hwsim.core.paths import write_text_atomic

    write_text_atomic(path, json.dumps(out, indent=1, sort_keys=True) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    from rtl.build import UNITS
    from rtl.fpga import DEFAULT_DEVICE

    parser = argparse.ArgumentParser(prog="python -m hwsim.studies.fpga")
    parser.add_argument("--device", default=DEFAULT_DEVICE)
    parser.add_argument("--jobs", type=int, default=2, help="runs at once (2)")
    parser.add_argument("--units", default="all", help="all, none or a comma list (all)")
    parser.add_argument(
        "--pipelines", default=",".join(map(str, TOP_PIPELINES)), help="the top's P, a list"
    )
    parser.add_argument("--rtl-commit", help="record this commit (a tree without .git)")
    parser.add_argument("--data", type=Path, help="the data file (hwsim/energy/data/...)")
    args = parser.parse_args(argv)
    named = {"all": list(UNITS), "none": []}
    units = named[args.units] if args.units in named else args.units.split(",")
    pipelines = [int(p) for p in args.pipelines.split(",") if p]
    target = args.data or Path(str(resources.files("hwsim.energy") / "data" / _DATA))
    refresh(target, args.device, args.jobs, units, pipelines, args.rtl_commit)
    print(f"wrote {target}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
