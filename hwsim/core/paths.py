"""Output paths: checked before any work starts, and recorded without the machine's paths.

Every command resolves, creates and tests each output folder and file it was given
before it loads or renders anything, so an unwritable ``--out``, ``--trace`` or ``--db``
is a one-line input error (exit status 2) up front, never a crash after minutes of
simulation.

A path an output records (``stats.json``, figures, benchmark JSON, sweep rows, the
report) is written by :func:`display_path`: relative to the run folder when inside it,
else to the repository (``../shared/...`` for its siblings), else to the working folder,
else as given; free text such as an error message goes through :func:`display_text`.
The tool keeps its resolved absolute paths for reading and for cache keys.
"""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path

from hwsim.core.errors import InputError

__all__ = [
    "output_folder",
    "output_file",
    "repo_root",
    "display_path",
    "display_text",
    "locate",
]


def output_folder(out_dir: str | Path, key: str = "--out") -> Path:
    """Create ``out_dir`` and check it is writable (bad input, exit 2, if not).

    Every command calls this for each of its output folders before any work starts, so
    an unwritable output is refused up front and never after minutes of simulation.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder", source=str(out), key=key)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"cannot create output folder: {exc.strerror}", source=str(out), key=key
        ) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError("output folder is not writable", source=str(out), key=key)
    return out


def output_file(path: str | Path, key: str) -> Path:
    """Create the folder of the output file ``path`` and check the file can be written."""
    target = Path(path)
    if target.is_dir():
        raise InputError("is a folder, expected a file name", source=str(target), key=key)
    output_folder(target.parent if str(target.parent) else Path("."), key=key)
    if target.exists() and not os.access(target, os.W_OK):
        raise InputError("output file is not writable", source=str(target), key=key)
    return target


@cache
def repo_root() -> Path | None:
    """The repository holding this package (the folder with ``pyproject.toml`` above
    ``hwsim/``), or None for an installed package."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() else None


def _anchors(base: str | Path | None) -> list[tuple[str, str]]:
    """Absolute folders a recorded path is made relative to, first match wins, each with
    the prefix its relative form takes (``..`` for the repository's siblings)."""
    found = [] if base is None else [(os.path.abspath(base), "")]
    root = repo_root()
    if root is not None:
        found.append((str(root), ""))
        if root.parent != root.parent.parent:  # not the file-system root
            found.append((str(root.parent), ".."))
    found.append((os.getcwd(), ""))
    return [(folder, prefix) for folder, prefix in found if folder != os.sep]


def display_path(path: str | Path, base: str | Path | None = None) -> str:
    """How an output records ``path``: never an absolute path of this machine.

    A relative path is returned as given.  An absolute one is made relative to ``base``
    (the run folder) when inside it, else to the repository when inside it (or
    ``../name/...`` for a sibling of the repository, such as ``../shared/data``), else to
    the working folder; a path outside all of them is returned as given.
    """
    text = str(path)
    if not os.path.isabs(text):
        return text
    candidates = dict.fromkeys([os.path.normpath(text), os.path.realpath(text)])
    for folder, prefix in _anchors(base):
        for target in candidates:
            for anchor in dict.fromkeys([folder, os.path.realpath(folder)]):
                if target == anchor or target.startswith(anchor.rstrip(os.sep) + os.sep):
                    rel = Path(os.path.relpath(target, anchor))
                    return (Path(prefix) / rel).as_posix() if prefix else rel.as_posix()
    return text


def display_text(text: str, base: str | Path | None = None) -> str:
    """``text`` (an error message, a note) with every absolute path under the folders of
    :func:`display_path` written as that function writes it."""
    for folder, prefix in _anchors(base):
        pattern = re.compile(r"(?<![\w./~-])" + re.escape(folder.rstrip(os.sep) + os.sep))
        text = pattern.sub(lambda _, short=f"{prefix}/" if prefix else "": short, text)
    return text


def locate(text: str, *bases: str | Path | None) -> Path:
    """The file a recorded path names: ``text`` itself when absolute, else the first of
    ``bases``, the repository and the working folder it exists under (``text`` as given
    when none has it)."""
    path = Path(text)
    if path.is_absolute():
        return path
    root = repo_root()
    for base in (*bases, root, Path.cwd()):
        if base is not None and (Path(base) / path).exists():
            return Path(base) / path
    return path
