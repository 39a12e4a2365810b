"""Reading validated, versioned TOML: every bad value names its file, key and range.

Scene files and architecture files both go through :class:`Table`, so every error a
user can make in either reads the same way::

    scenes/my.toml: view.azimuth: must be a number, got 'left' (allowed: -360 .. 360)
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError
from hwsim.core.paths import input_file

__all__ = ["Table", "read_toml"]

_MISSING = object()


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


class Table:
    """One TOML table being read: tracks its key path and refuses unknown keys.

    Parameters
    ----------
    data : dict
        The parsed table.
    source : str
        File name for error messages.
    path : str
        Dotted key path of this table inside the file ("" for the top level).
    """

    def __init__(self, data: dict[str, Any], source: str, path: str = "") -> None:
        if not isinstance(data, dict):
            got = f"{data!r}" if len(repr(data)) <= 40 else f"{repr(data)[:37]}..."
            raise InputError(f"must be a table, got {got}", source=source, key=path or "<top>")
        self.data = data
        self.source = source
        self.path = path
        self._seen: set[str] = set()

    def key(self, name: str) -> str:
        """Dotted path of ``name`` inside this table."""
        return f"{self.path}.{name}" if self.path else name

    def error(self, name: str, message: str, allowed: str | None = None) -> InputError:
        """An :class:`InputError` for key ``name`` of this table."""
        return InputError(message, source=self.source, key=self.key(name), allowed=allowed)

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: Any = _MISSING) -> Any:
        self._seen.add(name)
        if name in self.data:
            return self.data[name]
        if default is _MISSING:
            raise self.error(name, "is required")
        return default

    def table(self, name: str, required: bool = False) -> Table:
        value = self.raw(name, _MISSING if required else {})
        return Table(value, self.source, self.key(name))

    def tables(self, name: str) -> list[Table]:
        """An array of tables (``[[name]]``); empty when absent."""
        value = self.raw(name, [])
        if not isinstance(value, list):
            raise self.error(name, "must be an array of tables ([[...]])")
        return [Table(v, self.source, f"{self.key(name)}[{i}]") for i, v in enumerate(value)]

    def number(
        self,
        name: str,
        default: Any = _MISSING,
        lo: float | None = None,
        hi: float | None = None,
        *,
        lo_open: bool = False,
    ) -> float:
        value = self.raw(name, default)
        return check_number(value, self.source, self.key(name), lo, hi, lo_open=lo_open)

    def integer(
        self, name: str, default: Any = _MISSING, lo: int | None = None, hi: int | None = None
    ) -> int:
        value = self.raw(name, default)
        allowed = _range_text(lo, hi, integer=True)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f"must be an integer, got {value!r}", allowed)
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.error(name, f"{value} is out of range", allowed)
        return value

    def boolean(self, name: str, default: Any = _MISSING) -> bool:
        value = self.raw(name, default)
        if not isinstance(value, bool):
            raise self.error(name, f"must be true or false, got {value!r}", "true, false")
        return value

    def string(self, name: str, default: Any = _MISSING) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise self.error(name, f"must be a string, got {value!r}")
        return value

    def choice(self, name: str, choices: Iterable[str], default: Any = _MISSING) -> str:
        choices = list(choices)
        value = self.raw(name, default)
        if value not in choices:
            raise self.error(name, f"unknown value {value!r}", ", ".join(choices))
        return value

    def choices(
        self, name: str, allowed: Sequence[Any], default: Any = _MISSING
    ) -> tuple[Any, ...]:
        """A non-empty list of values from ``allowed`` (a machine's modes, voxel widths),
        each of the same type as the allowed value it equals (``8.0`` is not ``8``)."""
        value = self.raw(name, default)
        text = "a non-empty list of " + ", ".join(map(str, allowed))
        if not isinstance(value, list) or not value:
            raise self.error(name, f"must be a list, got {value!r}", text)
        for i, v in enumerate(value):
            if not any(type(v) is type(a) and v == a for a in allowed):
                raise self.error(name, f"unknown value {v!r} (item {i})", text)
        return tuple(value)

    def vector(
        self,
        name: str,
        length: int,
        default: Any = _MISSING,
        lo: float | None = None,
        hi: float | None = None,
    ) -> tuple[float, ...]:
        value = self.raw(name, default)
        if not isinstance(value, (list, tuple)) or len(value) != length:
            raise self.error(name, f"must be a list of {length} numbers, got {value!r}")
        return tuple(
            check_number(v, self.source, f"{self.key(name)}[{i}]", lo, hi)
            for i, v in enumerate(value)
        )

    def direction(self, name: str, default: Any = _MISSING) -> tuple[float, ...]:
        """A 3-vector that must not be zero (a light direction, a plane normal)."""
        value = self.vector(name, 3, default)
        if not any(value):
            raise self.error(name, "must not be the zero vector", "any non-zero [x, y, z]")
        return value

    def schema(self, version: int) -> None:
        """Read the ``schema`` key (absent: ``version``); any other version is refused."""
        schema = self.integer("schema", version)
        if schema != version:
            raise self.error("schema", f"unsupported schema {schema}", str(version))

    def finish(self) -> None:
        """Refuse keys nobody asked for (typos must not pass silently)."""
        unknown = sorted(set(self.data) - self._seen)
        if unknown:
            raise self.error(unknown[0], "unknown key", ", ".join(sorted(self._seen)) or "none")


def _range_text(
    lo: float | None, hi: float | None, *, integer: bool = False, lo_open: bool = False
) -> str:
    kind = "integer" if integer else "number"
    if lo is not None and hi is not None:
        return f"{'> ' if lo_open else ''}{lo:g} .. {hi:g}"
    if lo is not None:
        return f"{kind} {'>' if lo_open else '>='} {lo:g}"
    if hi is not None:
        return f"{kind} <= {hi:g}"
    return f"finite {kind}"


def check_number(
    value: Any,
    source: str,
    key: str,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
) -> float:
    """Validate one number: finite, inside ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""
    allowed = _range_text(lo, hi, lo_open=lo_open)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(
            f"must be a number, got {value!r}", source=source, key=key, allowed=allowed
        )
    value = float(value)
    if not math.isfinite(value):
        raise InputError(f"{value} is not finite", source=source, key=key, allowed=allowed)
    below = lo is not None and (value <= lo if lo_open else value < lo)
    if below or (hi is not None and value > hi):
        raise InputError(f"{value:g} is out of range", source=source, key=key, allowed=allowed)
    return value


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
