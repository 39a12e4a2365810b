"""The mutation mechanism of the evidence tier: a copy of the source tree with one side of
a comparison changed, run in a process of its own.

A comparison between two rungs is evidence only if it can fail.  Each test here copies
``hwsim/``, ``models/`` and ``rtl/`` into a temporary folder (no ``__pycache__``: numba
recompiles the copy's kernels from the mutated sources, never reusing a kernel that
froze an unmutated constant), applies its :class:`Edit` s there -- each an exact string
that must occur exactly once in its file, so a refactor that moves the text fails the
test loudly instead of testing nothing -- and runs the mutated side with ``side.py`` in
a subprocess whose ``PYTHONPATH`` is the copy (``side.py`` checks that ``hwsim``,
``models`` and ``rtl`` were imported from it, not from the venv's editable install).
The unmutated side runs the same way from the repository itself, so both sides take
the same path; the tests compare the two and assert that the comparison now fails,
and, as the control, that it passes between the unmutated sides.

The copy's RTL builds go to a folder of its own (``HWSIM_RTL_BUILD``), never to
``build/rtl``; the original tree's runs use the usual build cache.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
SIDE = Path(__file__).resolve().with_name("side.py")
#: What the copy holds: every package the rungs import from the repository.
PACKAGES = ("hwsim", "models", "rtl")
#: One side of a comparison at most this long (a cold Icarus build and frame: ~15 s).
TIMEOUT = 900


@dataclasses.dataclass(frozen=True)
class Edit:
    """Replace ``old`` by ``new`` in ``path`` (relative to the repository); ``old`` must
    occur exactly once."""

    path: str
    old: str
    new: str


@dataclasses.dataclass
class Side:
    """One side's result: ``side.py``'s ``result.json`` and its image, if any."""

    result: dict
    image: np.ndarray | None

    @property
    def cycles(self) -> int:
        return self.result["cycles"]

    def __getitem__(self, key):
        return self.result[key]


class SourceTree:
    """A source tree (the repository or a mutated copy) that runs ``side.py`` jobs."""

    def __init__(self, root: Path, work: Path, env: dict[str, str] | None = None) -> None:
        self.root, self.work, self.env = root.resolve(), work, env or {}
        self._runs = 0

    def run(self, job: str, **spec) -> Side:
        """Run ``job`` with ``spec`` in a process whose imports come from this tree."""
        self._runs += 1
        out = self.work / f"{job}-{self._runs}"
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        # One thread per frame: the tier runs beside other tests on two cores (the image
        # and cycles do not depend on it).
        env.update(PYTHONPATH=str(self.root), HWSIM_THREADS="1", **self.env)
        argv = [sys.executable, str(SIDE), str(self.root), job, str(out), json.dumps(spec)]
        done = subprocess.run(
            argv, cwd=self.root, env=env, capture_output=True, text=True, timeout=TIMEOUT
        )
        if done.returncode != 0:  # not an AssertionError: a broken run never passes as xfail
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-15:])
            raise RuntimeError(f"side.py {job} {spec} in {self.root} failed:\n{tail}")
        result = json.loads((out / "result.json").read_text())
        for name, file in result["files"].items():  # side.py checked it; checked again here
            assert Path(file).is_relative_to(self.root), (name, file)
        image = np.load(out / "image.npy") if (out / "image.npy").is_file() else None
        return Side(result, image)


def copy_tree(dest: Path, edits: tuple[Edit, ...]) -> Path:
    """``hwsim/``, ``models/`` and ``rtl/`` copied to ``dest`` with ``edits`` applied."""
    dest.mkdir(parents=True)
    for package in PACKAGES:
        shutil.copytree(
            REPO / package, dest / package, ignore=shutil.ignore_patterns("__pycache__")
        )
    for edit in edits:
        file = dest / edit.path
        text = file.read_text()
        count = text.count(edit.old)
        assert count == 1, f"{edit.path}: {edit.old!r} occurs {count} times, not once"
        file.write_text(text.replace(edit.old, edit.new))
    return dest


class CachedTree(SourceTree):
    """The repository's tree, each ``(job, spec)`` run once per test session."""

    def __init__(self, root: Path, work: Path) -> None:
        super().__init__(root, work)
        self._cache: dict[str, Side] = {}

    def run(self, job: str, **spec) -> Side:
        key = json.dumps([job, spec], sort_keys=True)
        if key not in self._cache:
            self._cache[key] = super().run(job, **spec)
        return self._cache[key]
