"""The ``rtl`` rung of the VolumePro 500: one frame of the vg500 top and its four SDRAM
devices under Verilator (or Icarus), Python only at the frame's edges.

# Ref: rtl/rung.py (the Cube-4 top's rung: the same build folders, flags and decoding).

The Verilog of the top, the bench (:mod:`rtl.vg500.bench`) and the devices and checkers
of ``rtl/sdram`` are built once per key: the pipelines' :func:`rtl.top_key.verilog_key`,
the source of ``rtl/vg500`` and ``rtl/sdram``, the SDRAM timing, the slab buffer's
capacity, the devices' rows and the simulator flags.  The volume goes into the devices
from one hex file per module (the host's write in the mini-block layout); the pixels come
back in a file.  The checkers' counters come back as ``memory.sdram.checker.*``: a
violation fails the run.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import resource
import time
from pathlib import Path

from hwsim.core import env
from hwsim.core.errors import NotAvailableError
from hwsim.core.notices import first_run
from hwsim.memory import parse_memory
from models.frame import Frame
from models.machines.common.results import CycleResult
from rtl.frame import decode
from rtl.rung import _VERILATOR_ARGS, REPO, _locked, _simulate, _unpack_pixel, require_simulator
from rtl.top_key import verilog_key
from rtl.top_layouts import pixel_layout
from rtl.vg500.frame import Vg500Program, device_image, prepare_vg500

__all__ = ["render_vg500", "run_vg500", "rows_for"]

_HERE = Path(__file__).resolve().parent
_SDRAM = REPO / "rtl" / "sdram"
#: The modules of this package that reach the Verilog (edits elsewhere keep the build).
_VERILOG_SOURCES = ("sdram_ctrl", "front_end", "top", "bench")
#: The Cube-4 rung's Verilator flags (-O3, --x-assign/--x-initial fast, one thread), the
#: C++ of the clock loop at -O2 for this machine's CPU and the run-once initialisation
#: code unoptimised (it is most of the C++ and runs once; the build is faster).
_VG500_ARGS = [a for a in _VERILATOR_ARGS if a not in ("-CFLAGS", "-O2")]
_VG500_ARGS += ["-CFLAGS", "-march=native", "-MAKEFLAGS", "OPT_FAST=-O2"]
_VG500_ARGS += ["-MAKEFLAGS", "OPT_GLOBAL=-O2", "-MAKEFLAGS", "OPT_SLOW=-O0"]


def rows_for(max_axis: int, columns: int = 512) -> int:
    """Device rows per bank the size class's largest volume uses (mini-block layout)."""
    nb = max_axis // 2
    pitch = -(-nb // 16) * 16
    words = ((nb * nb * pitch) // 16) * 8
    return -(-words // columns)


def _key(program: Vg500Program, rows: int, strict: bool) -> str:
    inner = program.inner
    h = hashlib.sha256(
        repr(
            (
                verilog_key(inner.dp, inner.geo),
                program.timing,
                program.slab_entries,
                rows,
                strict,
                _VG500_ARGS,
            )
        ).encode()
    )
    verilog = [_HERE / f"{name}.py" for name in _VERILOG_SOURCES]
    for path in sorted([*verilog, *_SDRAM.glob("*.v")]):
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:12]


def _folder(simulator: str, key: str) -> Path:
    root = env.value("HWSIM_RTL_BUILD") or REPO / "build" / "rtl"
    return Path(root) / f"{simulator}_vg500_{key}"


def _export(program: Vg500Program, rows: int, strict: bool, folder: Path) -> None:
    from rtl.export import to_verilog
    from rtl.vg500.bench import vg500_bench_verilog, vg500_main
    from rtl.vg500.sim import build_top

    top_v = folder / "vg500_top.v"
    if top_v.is_file():
        return
    folder.mkdir(parents=True, exist_ok=True)
    top = build_top(program)
    for path, text in (
        (folder / "vg500_bench.v", vg500_bench_verilog(top, rows, strict=strict)),
        (folder / "main.cpp", vg500_main()),
        (top_v, compact_memory_init(to_verilog(top, "vg500_top"))),
    ):
        tmp = folder / f"{path.name}.{os.getpid()}.tmp"
        tmp.write_text(text)
        tmp.replace(path)


_INIT_WORD = re.compile(r"^(\s+)(\\?[\w$.]+ ?)\[(\d+)\] = (\d+'h[0-9a-fA-F]+);$")


def compact_memory_init(verilog: str) -> str:
    """The export's memory initialisation, one assignment a word (``mem[i] = V;``, a
    whole-volume buffer's worth of lines for the C++ compiler), as one ``for`` loop per
    run of equal values: the same initial contents, a build that does not grow with the
    memories."""
    out: list[str] = []
    lines = verilog.splitlines()
    i, loops = 0, 0
    while i < len(lines):
        hit = _INIT_WORD.match(lines[i])
        j = i + 1
        if hit:
            indent, name, first, value = hit.groups()
            while j < len(lines):
                nxt = _INIT_WORD.match(lines[j])
                if not nxt or nxt.group(2, 4) != (name, value):
                    break
                if int(nxt.group(3)) != int(first) + (j - i):
                    break
                j += 1
        if not hit or j - i < 16:
            out.extend(lines[i:j])
            i = j
            continue
        var = f"init_word{loops}"
        loops += 1
        out.append(f"{indent}begin : {var}_loop")
        out.append(f"{indent}  integer {var};")
        end = int(first) + (j - i)
        out.append(
            f"{indent}  for ({var} = {first}; {var} < {end}; {var} = {var} + 1) "
            f"{name}[{var}] = {value};"
        )
        out.append(f"{indent}end")
        i = j
    return "\n".join(out) + "\n"


def _build(folder: Path, simulator: str) -> Path:
    import subprocess

    exe = folder / ("Vvg500_bench" if simulator == "verilator" else "vg500.vvp")
    if exe.is_file():
        return exe
    sources = [str(folder / "vg500_bench.v"), str(folder / "vg500_top.v")]
    sources += [str(_SDRAM / "sdr_sdram.v"), str(_SDRAM / "sdram_checker.v")]
    if simulator == "verilator":
        cmd = ["verilator", *_VG500_ARGS, "--cc", "--exe", "--build", "-j", "2"]
        cmd += ["--top-module", "vg500_bench", "-Mdir", str(folder), "-o", exe.name]
        cmd += [str(folder / "main.cpp"), *sources]
    else:
        raise NotImplementedError("the vg500 bench runs on Verilator")
    log = folder / "build.log"
    with open(log, "w") as handle:
        done = subprocess.run(cmd, stdout=handle, stderr=subprocess.STDOUT, check=False)
    if done.returncode != 0 or not exe.is_file():
        raise RuntimeError(f"{simulator} build of the vg500 top failed; see {log}")
    return exe


def run_vg500(
    program: Vg500Program, simulator: str = "verilator", *, strict: bool = False, progress=None
) -> tuple[CycleResult, dict]:
    """Run one frame; returns the result and timings (``build_seconds``, ``run_seconds``,
    ``sim_seconds``: the clock loop alone, ``cpu_seconds``: the simulator process's CPU
    time, ``clocks``) and the memory's counters."""
    require_simulator(simulator)
    if simulator != "verilator":
        raise NotAvailableError(
            "the vg500 bench runs on Verilator only", key="--simulator", allowed="verilator"
        )
    t0 = time.perf_counter()
    inner = program.inner
    rows = rows_for(inner.geo.max_axis, program.timing.columns)
    key = _key(program, rows, strict)
    folder = _folder(simulator, key)
    folder.mkdir(parents=True, exist_ok=True)
    exe_name = "Vvg500_bench" if simulator == "verilator" else "vg500.vvp"
    built = (folder / exe_name).is_file()
    with contextlib.nullcontext() if built else first_run("building the vg500 RTL, first run only"):
        with _locked(folder):
            _export(program, rows, strict, folder)
            exe = _build(folder, simulator)
    t1 = time.perf_counter()
    pid = os.getpid()
    scratch = {"loads": folder / f"loads_{pid}.hex", "pixels": folder / f"pixels_{pid}.hex"}
    arch = inner.backend.arch
    memory = parse_memory(arch.memory, source=arch.source)
    _, images = device_image(inner.backend.raw, memory, program.timing, rows=rows)
    for k, words in enumerate(images):
        scratch[f"sdram{k}"] = folder / f"sdram{k}_{pid}.hex"
        scratch[f"sdram{k}"].write_text("".join(f"{w:x}\n" for w in words))
    words = inner.load_words()
    scratch["loads"].write_text("".join(f"{w:x}\n" for w in words))
    regs = inner.registers
    limit = len(words) + 64 * (regs["n_a"] * regs["c"] + 64) * (regs["n_kp"] + 2) + 10_000
    plusargs = [f"+{k}={v}" for k, v in scratch.items() if k != "pixels"]
    plusargs += [f"+pixels={scratch['pixels']}", f"+nloads={len(words)}", f"+limit={limit}"]
    plusargs += [f"+r_{name}={int(value):x}" for name, value in regs.items()]
    try:
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        returncode, output = _simulate([str(exe), *plusargs], inner.plan.samples, progress)
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        line = next((x for x in output if x.startswith("HWSIM ")), None)
        extra = next((x for x in output if x.startswith("HWSIM_VG500 ")), None)
        if returncode != 0 or line is None or extra is None:
            raise RuntimeError(
                f"{simulator} run of the vg500 top failed: {' | '.join(output[-3:])}"
            )
        raw = json.loads(line[len("HWSIM ") :])
        mem = json.loads(extra[len("HWSIM_VG500 ") :])
        if not raw["finished"]:
            raise RuntimeError(f"the vg500 top did not finish in {limit} clocks")
        lay = pixel_layout(inner.geo, inner.dp)
        pixels = [_unpack_pixel(lay, int(w, 16)) for w in scratch["pixels"].read_text().split()]
    finally:
        for path in scratch.values():
            path.unlink(missing_ok=True)
    t2 = time.perf_counter()
    result = decode(inner, pixels, raw["cycles"], raw["samples"], raw["stall_cycles"])
    result.counters["rtl.simulator"] = simulator
    result.counters["rtl.simulated_clocks"] = raw["clocks"]
    result.counters["memory.hold_cycles"] = mem["hold_cycles"]
    result.counters["memory.bursts"] = mem["bursts"]
    # the frame's refreshes, first request to last READ (the cycle rung's count)
    result.counters["memory.sdram.frame_refreshes"] = mem["frame_refreshes"]
    for name in ("violations", "activates", "reads", "precharges", "refreshes"):
        result.counters[f"memory.sdram.checker.{name}"] = mem[name]
    violations = [x for x in output if "violat" in x.lower() or "breach" in x.lower()]
    if mem["violations"]:
        raise RuntimeError(
            f"the SDRAM checkers found {mem['violations']} violations: {' | '.join(violations[:3])}"
        )
    timing = {
        "build_seconds": t1 - t0,
        "run_seconds": t2 - t1,
        "sim_seconds": raw.get("seconds"),
        # the simulator process's CPU time (its file loads included): speed under load
        "cpu_seconds": (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime),
        "clocks": raw["clocks"],
    }
    return result, timing


def render_vg500(frame: Frame, *, simulator: str = "verilator", progress=None) -> CycleResult:
    """The rtl rung's frame on the vg500 top."""
    return run_vg500(prepare_vg500(frame), simulator, progress=progress)[0]
