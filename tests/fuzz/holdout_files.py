"""The hold-out's shared parts (tests/fuzz/holdout_cases.py runs it): the case record,
the registrar of each table module's cases (:func:`registrar`), the command lines every
case starts from and the builders of the files a case writes into its folder
(architecture, technology, scene, sweep, volume and run folders, FIFOs, symbolic-link
loops, sockets).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
HWSIM = [sys.executable, "-m", "hwsim.cli.commands"]
RENDER = ["render", "--phantom", "head:size=8", "--image", "8", "--quiet", "--out", "out"]
CYCLE = ["--fidelity", "cycle", "--arch", "cube4"]
SCENE = """schema = 1
[volume]
phantom = "ball"
params = { size = 8 }
[view]
width = 8
height = 8
"""
SWEEP = 'schema = 1\n[sweep]\nphantom = ["ball:size=8"]\nfidelity = ["golden"]\nimage = [8]\n'
LONG = "n" * 300
#: A case still running after this long failed to refuse its input up front.
TIMEOUT = 300


@dataclass
class Setup:
    """What one case runs: argv, extra environment, the files it must leave as they
    were, and whether a correct result is also acceptable ("either")."""

    argv: list[str]
    env: dict[str, str]
    keep: list[Path]
    expect: str = "error"


@dataclass
class Case:
    name: str
    kind: str
    build: Callable[[Path], Setup]


def registrar(cases: list[Case]) -> Callable:
    """The decorator ``case(kind, expect="error")`` of one table module: it appends the
    decorated builder (``d -> (argv, keep[, env])``) to ``cases`` as a :class:`Case`
    named after it, in the order of the module's definitions."""

    def case(kind: str, expect: str = "error"):
        def register(fn: Callable[[Path], tuple]) -> Callable:
            def build(d: Path) -> Setup:
                argv, keep, *env = fn(d)
                return Setup(argv, env[0] if env else {}, keep, expect)

            cases.append(Case(fn.__name__, kind, build))
            return fn

        return register

    return case


# ------------------------------------------------------------------ file builders


def _arch(d: Path, old: str, new: str, name: str = "a.toml") -> Path:
    text = (REPO / "models/machines/cube4/cube4.toml").read_text()
    assert old in text, old
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.replace(old, new, 1))
    return path


def _tech(d: Path, old: str = "", new: str = "", name: str = "t.toml") -> Path:
    text = (REPO / "hwsim/energy/technologies/cmos45.toml").read_text()
    assert old in text, old
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.replace(old, new, 1) if old else text)
    return path


def _derived(d: Path, base: str, name: str = "d.toml") -> Path:
    text = (REPO / "hwsim/energy/technologies/cmos250.toml").read_text()
    assert 'base = "cmos45"' in text
    path = d / name
    path.write_text(text.replace('base = "cmos45"', f'base = "{base}"'))
    return path


def _scene(d: Path, old: str = "", new: str = "", extra: str = "") -> Path:
    path = d / "s.toml"
    path.write_text((SCENE.replace(old, new, 1) if old else SCENE) + extra)
    return path


def _file(d: Path, name: str, text: str | bytes) -> Path:
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _volume(d: Path, name: str = "v.npy", shape=(8, 8, 8), dtype=np.uint8) -> Path:
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, (np.arange(np.prod(shape)) % 200).astype(dtype).reshape(shape))
    return path


def _nrrd(d: Path, header: str, data: bytes = bytes(64)) -> Path:
    return _file(d, "v.nrrd", ("NRRD0004\n" + header + "\n\n").encode() + data)


def _run_dir(d: Path, stats: str | None = None, image: np.ndarray | None = None) -> Path:
    run = d / "run"
    run.mkdir(exist_ok=True)
    _file(run, "stats.json", stats if stats is not None else _valid_stats())
    if image is not None:
        np.save(run / "image.npy", image, allow_pickle=False)
    return run


_VALID: dict[str, str] = {}


def _valid_stats() -> str:
    """A real render's stats.json (made once per process)."""
    if "stats" not in _VALID:
        with tempfile.TemporaryDirectory() as tmp:
            done = subprocess.run([*HWSIM, *RENDER], cwd=tmp, capture_output=True, text=True)
            assert done.returncode == 0, done.stderr
            _VALID["stats"] = (Path(tmp) / "out" / "stats.json").read_text()
    return _VALID["stats"]


def _fifo(d: Path, name: str) -> Path:
    path = d / name
    os.mkfifo(path)
    return path


def _loop(d: Path, name: str) -> Path:
    path = d / name
    os.symlink(name, path)  # points at itself
    return path


#: Sockets the cases leave bound (their files stay sockets); the runner closes them.
_SOCKETS: list[socket.socket] = []
