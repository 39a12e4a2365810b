"""Ctrl-C (issue 33): SIGINT stops a render or a sweep at its next step, exit status 130,
one line, no final output.

Each test starts the command line in a subprocess with a frame large enough to run for a
long while, waits until its progress bar shows it is under way (tqdm shows a bar after a
second of work), sends SIGINT and waits for the exit.  The timeout only guards against a
hang (an interrupt that is ignored lets the frame run to its end, minutes here); nothing
is asserted about the time taken.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
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


def _interrupt_when_started(args: list[str], marker: str) -> tuple[int, str]:
    """Run ``hwsim ARGS``, send SIGINT once ``marker`` is on its stderr; its exit status
    and the stderr written after the marker."""
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
