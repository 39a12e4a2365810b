"""Reading TOML: a missing, unreadable or malformed file is one line naming it.

What a parsed document may hold is its file kind's model's to say (:mod:`hwsim.core.models`:
scene, architecture, technology, sweep), so every error a user can make in any of them
reads the same way::

    scenes/my.toml: view.azimuth: must be a number, got 'left' (allowed: -360 .. 360)
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError
from hwsim.core.paths import input_file

__all__ = ["flatten_table", "read_toml"]


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file raises :class:`InputError`."""
    path = input_file(path)  # a FIFO or a device is refused, never opened
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise InputError("not UTF-8 text", source=str(path)) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"malformed TOML: {exc}", source=str(path)) from None
    except RecursionError:  # tomllib recurses once per nesting level
        raise InputError(
            "nested too deeply", source=str(path), allowed="a few levels of tables and arrays"
        ) from None


def flatten_table(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested tables as dotted keys: ``{"interp": {"weight_bits": 9}}`` (how TOML reads
    ``interp.weight_bits = 9``) becomes ``{"interp.weight_bits": 9}``."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            out.update(flatten_table(value, name))
        else:
            out[name] = value
    return out
