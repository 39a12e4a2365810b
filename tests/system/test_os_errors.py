"""Operating-system errors and non-regular files, through the real command line.

Every ``OSError`` a command meets (a name too long, a symlink loop, permission denied)
and every input that is not a regular file (a named pipe, a device, a socket) must end
in one line on stderr naming the path, exit status 2: no traceback, no "internal error",
and no hang (a FIFO opened for reading waits for a writer forever).  The subprocess
timeout below is only a hang guard: reaching it fails the test.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

HWSIM = [sys.executable, "-m", "hwsim.cli.commands"]
#: Far above any case's run time (about 3 s); only a hung command reaches it.
HANG_GUARD_S = 300
LONG = "n" * 300  # one path component past NAME_MAX (255 bytes)


def run_cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "HWSIM_DEBUG": "", "PYTHONWARNINGS": "error"}
    try:
        return subprocess.run(
            [*HWSIM, *args],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=HANG_GUARD_S,
            env=env,
            stdin=subprocess.DEVNULL,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"hwsim {' '.join(args)} hung (no answer in {HANG_GUARD_S} s)")


def assert_one_line(done: subprocess.CompletedProcess, *fragments: str) -> None:
    err = done.stderr
    assert done.returncode == 2, (done.returncode, err)
    assert err.count("\n") == 1 and err.startswith("hwsim: error: "), err
    assert "Traceback" not in err and "internal error" not in err, err
    for fragment in fragments:
        assert fragment in err, (fragment, err)


@pytest.fixture
def work(tmp_path: Path) -> Path:
    """A folder with one good small volume, scene, sweep and run folder to point at."""
    np.save(tmp_path / "vol.npy", np.zeros((4, 4, 4), np.uint8))
    (tmp_path / "scene.toml").write_text('[volume]\nphantom = "ball"\nparams = { size = 8 }\n')
    return tmp_path


_RENDER = ["render", "--phantom", "ball:size=8", "--image", "8"]

#: Every path-taking flag and positional, given a 300-character name.
LONG_NAMES = {
    "render --out": [*_RENDER, "--out", LONG],
    "render --out (inside)": [*_RENDER, "--out", f"sub/{LONG}/x"],
    "render --volume": ["render", "--volume", f"{LONG}.nrrd", "--out", "o"],
    "render scene": ["render", f"{LONG}.toml", "--out", "o"],
    "render --arch": [*_RENDER, "--arch", f"{LONG}.toml", "--out", "o"],
    "render --technology": [*_RENDER, "--technology", f"{LONG}.toml", "--out", "o"],
    "render --transfer": [*_RENDER, "--transfer", f"{LONG}.toml", "--out", "o"],
    "render --trace": [*_RENDER, "--fidelity", "cycle", "--trace", f"{LONG}.vcd", "--out", "o"],
    "convert IN": ["convert", f"{LONG}.npy", "out.nrrd"],
    "convert OUT": ["convert", "vol.npy", f"{LONG}.nrrd"],
    "sweep FILE": ["sweep", f"{LONG}.toml", "--out", "o"],
    "sweep --db": ["sweep", "scene.toml", "--db", f"{LONG}.db", "--out", "o"],
    "report RUN_DIR": ["report", LONG, "--out", "o"],
    "report --out": ["report", "o", "--out", LONG],
    "rtl build --out": ["rtl", "build", "interp", "--no-synth", "--out", LONG],
}


@pytest.mark.parametrize("args", LONG_NAMES.values(), ids=LONG_NAMES.keys())
def test_a_name_too_long_is_one_line(work, args):
    assert_one_line(run_cli(args, work))


def _fifo(folder: Path, name: str) -> Path:
    path = folder / name
    os.mkfifo(path)
    return path


#: Each input kind, given as a named pipe: (file name, command line using it).
FIFO_INPUTS = {
    "--volume .nrrd": ("v.nrrd", ["render", "--volume", "v.nrrd", "--out", "o"]),
    "--volume .npy": ("v.npy", ["render", "--volume", "v.npy", "--out", "o"]),
    "--volume .nii": ("v.nii", ["render", "--volume", "v.nii", "--out", "o"]),
    "--volume .raw": (
        "v.raw",
        ["render", "--volume", "v.raw", "--shape", "4,4,4", "--dtype", "uint8", "--out", "o"],
    ),
    "--volume --workers": (
        "v.npy",
        ["render", "--volume", "v.npy", "--fidelity", "cycle", "--workers", "2", "--out", "o"],
    ),
    "scene": ("s.toml", ["render", "s.toml", "--out", "o"]),
    "--arch": ("a.toml", [*_RENDER, "--arch", "a.toml", "--fidelity", "functional"]),
    "--technology": ("t.toml", [*_RENDER, "--technology", "t.toml", "--out", "o"]),
    "--transfer .toml": ("tf.toml", [*_RENDER, "--transfer", "tf.toml", "--out", "o"]),
    "--transfer .npy": ("tf.npy", [*_RENDER, "--transfer", "tf.npy", "--out", "o"]),
    "sweep FILE": ("sw.toml", ["sweep", "sw.toml", "--out", "o"]),
    "convert IN": ("c.nrrd", ["convert", "c.nrrd", "out.npy"]),
    "report stats.json": ("run/stats.json", ["report", "run", "--out", "rep"]),
    "report image.npy": ("run/image.npy", ["report", "run", "--out", "rep"]),
}


@pytest.mark.parametrize("name,args", FIFO_INPUTS.values(), ids=FIFO_INPUTS.keys())
def test_a_named_pipe_is_refused_unopened(work, name, args):
    if name.startswith("run/"):  # a real run folder, one of its files then a pipe
        from hwsim.cli.commands import main

        assert main([*_RENDER, "--quiet", "--out", str(work / "run")]) == 0
        (work / name).unlink()
    fifo = _fifo(work, name)
    assert_one_line(run_cli(args, work), fifo.name, "named pipe")


def test_a_nrrd_whose_data_file_is_a_pipe_is_refused(work):
    _fifo(work, "data.raw")
    (work / "v.nhdr").write_text(
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: data.raw\n\n"
    )
    done = run_cli(["render", "--volume", "v.nhdr", "--out", "o"], work)
    assert_one_line(done, "data.raw", "data file", "named pipe")


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/null"])
def test_a_device_is_refused(work, device):
    (work / "dev.nrrd").symlink_to(device)
    (work / "dev.toml").symlink_to(device)
    for args in (
        ["render", "--volume", "dev.nrrd", "--out", "o"],
        ["render", "dev.toml", "--out", "o"],
        ["render", "--volume", device, "--out", "o"],
    ):
        assert_one_line(run_cli(args, work), "character device")


def test_a_socket_is_refused(work):
    with socket.socket(socket.AF_UNIX) as sock:
        sock.bind(str(work / "s.nrrd"))
        assert_one_line(run_cli(["render", "--volume", "s.nrrd", "--out", "o"], work), "socket")


def test_a_pipe_as_output_is_refused(work):
    """Opening a FIFO to write waits for a reader: an output that is one is refused."""
    _fifo(work, "wave.vcd")
    args = [*_RENDER, "--fidelity", "cycle", "--trace", "wave.vcd", "--out", "o"]
    assert_one_line(run_cli(args, work), "wave.vcd", "named pipe")


@pytest.mark.parametrize(
    "args",
    [
        ["render", "--volume", "loop.nrrd", "--out", "o"],
        ["render", "loop.toml", "--out", "o"],
        [*_RENDER, "--arch", "loop.toml"],
        ["convert", "loop.nrrd", "x.npy"],
        [*_RENDER, "--out", "loopdir/o"],
    ],
    ids=["--volume", "scene", "--arch", "convert IN", "--out"],
)
def test_a_symlink_loop_is_one_line(work, args):
    for name in ("loop.nrrd", "loop.toml", "loopdir"):
        (work / name).symlink_to(name)
    assert_one_line(run_cli(args, work), "loop")


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a chmod 000 file anyway")
@pytest.mark.parametrize(
    "args",
    [
        ["render", "--volume", "locked/vol.npy", "--out", "o"],
        ["render", "locked/scene.toml", "--out", "o"],
        [*_RENDER, "--out", "locked/o"],
    ],
    ids=["--volume", "scene", "--out"],
)
def test_an_unreadable_folder_is_one_line(work, args):
    locked = work / "locked"
    locked.mkdir()
    np.save(locked / "vol.npy", np.zeros((4, 4, 4), np.uint8))
    (locked / "scene.toml").write_text("")
    locked.chmod(0)
    try:
        assert_one_line(run_cli(args, work), "locked", "ermission denied")
    finally:
        locked.chmod(0o755)


def test_the_boundary_turns_any_os_error_into_one_line(monkeypatch, capsys):
    """The class, not the cases: an OSError raised anywhere under a command (here: no
    space left, from a command body) is one line naming the path, exit 2."""
    import errno

    from hwsim.cli import commands

    def no_space(args):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "/out/image.npy")

    monkeypatch.setitem(commands._COMMANDS, "scenes", no_space)
    assert commands.main(["scenes"]) == 2
    err = capsys.readouterr().err
    assert err == "hwsim: error: /out/image.npy: no space left on device\n"


def test_a_genuine_bug_is_still_an_internal_error(monkeypatch, capsys):
    from hwsim.cli import commands

    def bug(args):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setitem(commands._COMMANDS, "scenes", bug)
    monkeypatch.delenv("HWSIM_DEBUG", raising=False)
    assert commands.main(["scenes"]) == 1
    assert "internal error: ZeroDivisionError" in capsys.readouterr().err


# --------------------------------------------------------------------- the property

#: (role, command line with PATH where the odd path goes): every path-taking argument.
ROLES = {
    "folder out": [
        [*_RENDER, "--out", "PATH"],
        ["report", "run", "--out", "PATH"],
        ["rtl", "build", "interp", "--no-synth", "--out", "PATH"],
    ],
    "file out": [
        [*_RENDER, "--fidelity", "cycle", "--trace", "PATH", "--out", "o"],
        ["convert", "vol.npy", "PATH"],
        ["sweep", "scene.toml", "--db", "PATH", "--out", "o"],
    ],
    "file in": [
        ["render", "--volume", "PATH", "--out", "o"],
        ["render", "PATH", "--out", "o"],
        [*_RENDER, "--arch", "PATH", "--out", "o"],
        [*_RENDER, "--technology", "PATH", "--out", "o"],
        [*_RENDER, "--transfer", "PATH", "--out", "o"],
        ["convert", "PATH", "out.npy"],
        ["sweep", "PATH", "--out", "o"],
        ["report", "PATH", "--out", "rep"],
    ],
}


def _odd_path(folder: Path, kind: str, role: str, suffix: str) -> str:
    """A path of ``kind`` in ``folder`` that is wrong for ``role``."""
    (folder / "afile").write_text("x")
    (folder / "adir").mkdir(exist_ok=True)
    if kind == "long":
        return f"{LONG}{suffix}"
    if kind == "long inside":
        return f"adir/{LONG}/x{suffix}"
    if kind == "loop":
        (folder / f"loop{suffix}").symlink_to(f"loop{suffix}")
        return f"loop{suffix}"
    if kind == "under a file":
        return f"afile/x{suffix}"
    if kind == "dangling":
        (folder / f"gone{suffix}").symlink_to("nowhere/at/all")
        return f"gone{suffix}"
    if kind == "device":
        (folder / f"dev{suffix}").symlink_to("/dev/null")
        return f"dev{suffix}"
    # "wrong kind": a file where a folder goes, a folder where a file goes or is read
    if role == "folder out":
        return "afile"
    (folder / f"adir{suffix}").mkdir(exist_ok=True)
    return f"adir{suffix}"


@settings(max_examples=60, deadline=None)
@given(
    role_args=st.sampled_from([(role, args) for role, lines in ROLES.items() for args in lines]),
    kind=st.sampled_from(
        ["long", "long inside", "loop", "under a file", "dangling", "device", "wrong kind"]
    ),
    suffix=st.sampled_from(["", ".toml", ".nrrd", ".npy", ".vcd", ".db"]),
)
def test_any_odd_path_anywhere_is_one_line_exit_2(role_args, kind, suffix):
    """The class: whatever path argument gets whichever odd path, the command ends with
    exit 2 and one line on stderr, never an internal error (in-process: fast)."""
    import contextlib
    import io
    import tempfile

    from hwsim.cli.commands import main

    role, args = role_args
    assume(not (role == "file out" and kind == "dangling"))  # the link itself is replaced
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        np.save(folder / "vol.npy", np.zeros((4, 4, 4), np.uint8))
        (folder / "scene.toml").write_text('[volume]\nphantom = "ball"\n')
        odd = _odd_path(folder, kind, role, suffix)
        argv = [odd if a == "PATH" else a for a in args]
        err = io.StringIO()
        cwd = os.getcwd()
        os.chdir(folder)
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                status = main(argv)
        finally:
            os.chdir(cwd)
    text = err.getvalue()
    assert "internal error" not in text and "Traceback" not in text, (argv, text)
    assert status == 2 and text.count("\n") == 1 and text.startswith("hwsim: error: "), (
        argv,
        status,
        text,
    )
