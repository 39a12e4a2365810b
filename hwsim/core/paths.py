"""Output paths, checked before any work starts.

Every command resolves, creates and tests each output folder and file it was given
before it loads or renders anything, so an unwritable ``--out``, ``--trace`` or ``--db``
is a one-line input error (exit status 2) up front, never a crash after minutes of
simulation.
"""

from __future__ import annotations

import os
from pathlib import Path

from hwsim.core.errors import InputError

__all__ = ["output_folder", "output_file"]


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
