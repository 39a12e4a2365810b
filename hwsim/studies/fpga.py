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

``python -m hwsim.studies.fpga [--device PART] [--jobs N]`` re-measures every unit and the
Cube-4 top at P = 1 and the pipeline counts in :data:`TOP_PIPELINES` and writes
``hwsim/energy/data/units_fpga.json`` (tens of minutes on two cores).
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
#: The Cube-4 top's pipeline counts :func:`refresh` routes (P = 1 and the largest that
#: fits an LFE5U-85F, found by trying: docs/rtl.md).
TOP_PIPELINES = (1, 4)


def what_if(record: dict[str, Any], arch) -> dict[str, Any]:
    """``what_if_frame_rate`` and its basis for a routed top (``{}`` for a unit)."""
    from hwsim.run.fidelity import render, resolve_arch
    from hwsim.studies.figures import figure_machine, figure_scene, published_figures

    if record["target"] not in ("top", "cube4") or not record.get("fmax_mhz"):
        return {}
    pipelines = record["params"]["pipelines"]
    size = min(record["params"]["max_axis"], 128)
    machine = figure_machine(dataclasses.replace(resolve_arch("cube4"), pipelines=pipelines))
    run = render(figure_scene(size), fidelity="cycle", arch=machine)
    fmax_hz = record["fmax_mhz"] * 1e6
    teramac = resolve_arch("cube4-teramac")
    published = {f.key: f.value for f in published_figures(teramac)}
    return {
        "what_if_frame_rate": fmax_hz / run.cycles,
        "what_if": {
            "what": WHAT_IF,
            "scene": f"dense head {size}^3 (the figures' scenario), cycle rung",
            "machine": f"cube4 at P = {pipelines}, {max(machine.value_bits)}-bit voxels",
            "cycles": int(run.cycles),
            "fmax_mhz": record["fmax_mhz"],
            "seconds": run.cycles / fmax_hz,
            "teramac_clock_mhz": teramac.clock_hz / 1e6,
            "teramac_frame_rate_same_cycles": teramac.clock_hz / run.cycles,
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


def refresh(path: Path, device: str, jobs: int) -> dict[str, Any]:
    """Route every unit and the top (P = each of :data:`TOP_PIPELINES`); write ``path``."""
    from rtl.build import UNITS

    runs = [(u, []) for u in UNITS]
    runs += [("cube4", [f"top.pipelines={p}"]) for p in TOP_PIPELINES]
    head = subprocess.run(
        ["git", "log", "-1", "--format=%h", "--", "rtl", "models/units"],
        capture_output=True, text=True, check=False, cwd=Path(__file__).parents[2],
    )  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="hwsim-fpga-") as tmp:
        with ThreadPoolExecutor(jobs) as pool:
            done = list(pool.map(lambda r: _measure(*r, device, Path(tmp)), runs))
    units = dict(zip(UNITS, done, strict=False))
    tops = {f"cube4-P{p}": r for p, r in zip(TOP_PIPELINES, done[len(UNITS) :], strict=True)}
    out = {
        "schema": 1,
        "what": "every unit and the Cube-4 top placed and routed on an ECP5 (rtl/fpga.py)",
        "command": f"python -m hwsim.studies.fpga --device {device}",
        "rtl_commit": head.stdout.strip() or None,
        "date": time.strftime("%Y-%m-%d"),
        "device": device,
        "units": units,
        "tops": tops,
    }
    from hwsim.core.paths import write_text_atomic

    write_text_atomic(path, json.dumps(out, indent=1, sort_keys=True) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    from rtl.fpga import DEFAULT_DEVICE

    parser = argparse.ArgumentParser(prog="python -m hwsim.studies.fpga")
    parser.add_argument("--device", default=DEFAULT_DEVICE)
    parser.add_argument("--jobs", type=int, default=2, help="runs at once (2)")
    args = parser.parse_args(argv)
    target = Path(str(resources.files("hwsim.energy") / "data" / "units_fpga.json"))
    refresh(target, args.device, args.jobs)
    print(f"wrote {target}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
