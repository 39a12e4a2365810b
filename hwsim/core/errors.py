"""Error types shared by the library and the CLI.

A user mistake (bad file, bad key, out-of-range value) raises :class:`InputError`;
the CLI prints it as one line on stderr and exits with status 2.  Anything else is an
internal fault (exit status 1).
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["HwsimError", "InputError", "NotAvailableError", "warn_user", "one_line_warnings"]


class HwsimError(Exception):
    """Base class of every error hwsim raises on purpose."""


class InputError(HwsimError):
    """Bad input from the user: one line naming the file, the key and the allowed range.

    Parameters
    ----------
    message : str
        What is wrong, e.g. ``"must be a number"``.
    source : str, optional
        The file (or ``"--flag"``) the value came from.
    key : str, optional
        Dotted key path inside the file, e.g. ``"view.azimuth"``.
    allowed : str, optional
        The allowed range or set, e.g. ``"-360 .. 360"``.
    """

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        key: str | None = None,
        allowed: str | None = None,
    ) -> None:
        self.message = message
        self.source = source
        self.key = key
        self.allowed = allowed
        super().__init__(str(self))

    def __str__(self) -> str:
        parts = [p for p in (self.source, self.key) if p]
        text = ": ".join([*parts, self.message])
        if self.allowed:
            text += f" (allowed: {self.allowed})"
        return text.replace("\n", " ")


class NotAvailableError(InputError):
    """A feature the user asked for that this build does not have yet (exit status 2)."""


def warn_user(source: str, message: str) -> None:
    """Tell the user something worth knowing about their input, as one stderr line."""
    text = " ".join(str(message).split())
    print(f"hwsim: warning: {source}: {text}", file=sys.stderr)


@contextmanager
def one_line_warnings(source: str) -> Iterator[None]:
    """Catch the warnings a library (NumPy, nibabel, pydicom) raises while reading
    ``source`` and pass each on once as a :func:`warn_user` line, never as a Python
    source line on stderr."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for message in dict.fromkeys(str(w.message) for w in caught):
        warn_user(source, message)
