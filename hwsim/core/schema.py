"""Declared shapes of the JSON files hwsim reads back, and a depth-limited JSON reader.

TOML inputs are read key by key through :class:`hwsim.core.config.Table`; the JSON files
hwsim wrote itself and reads again (``stats.json``, ``trade.json``, ``figures.json``) are
checked whole against a shape declared once per file kind, at load, so a hand-edited or
truncated file is one line naming the file and the key path::

    run/stats.json: volume.shape_zyx[1]: must be an integer, got 'x'

A shape is a Python value:

* ``str``, ``int``, ``float`` (any JSON number), ``bool``, ``Any``: a value of that type;
* ``{"key": shape, ...}``: an object with at least these keys (others are allowed, so
  a newer hwsim's extra fields read);
* :class:`Opt` ``(shape)`` as a value of such a dict: the key may be absent or ``null``
  (``Opt(shape, null=False)``: absent, but never ``null``);
* ``[shape]``: an array of values of ``shape``;
* :class:`MapOf` ``(shape)``: an object whose every value has ``shape``;
* :class:`OneOf` ``(a, b, ...)``: any of the shapes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError
from hwsim.core.paths import file_kind

__all__ = ["MAX_DEPTH", "MapOf", "OneOf", "Opt", "check_shape", "read_json"]

#: Deepest nesting of arrays and objects a JSON input may have (hwsim writes at most ~6).
MAX_DEPTH = 64


@dataclass(frozen=True)
class Opt:
    """A key that may be absent, or ``null`` too unless ``null=False`` (a value read
    with ``.get(key, default)``: absent gives the default, null would not)."""

    shape: Any
    null: bool = True


@dataclass(frozen=True)
class MapOf:
    """An object of any keys whose values all have ``shape``."""

    shape: Any


@dataclass(frozen=True)
class OneOf:
    """A value of any of ``shapes``."""

    shapes: tuple[Any, ...]

    def __init__(self, *shapes: Any) -> None:
        object.__setattr__(self, "shapes", shapes)


def _depth(text: str) -> int:
    """Deepest bracket nesting of JSON ``text`` (brackets inside strings skipped)."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def read_json(path: str | Path, shape: Any = Any, *, source: str | None = None) -> Any:
    """Parse a JSON file and check it against ``shape``; every failure is one
    :class:`InputError` naming the file (``source``, default the path)."""
    path = Path(path)
    source = source or str(path)
    if file_kind(path) not in (None, "a file", "a folder"):  # a FIFO or a device
        raise InputError(f"is {file_kind(path)}, expected a JSON file", source=source)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise InputError("file not found", source=source) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a JSON file", source=source) from None
    except UnicodeDecodeError:
        raise InputError("not UTF-8 text", source=source) from None
    except OSError as exc:
        raise InputError(f"unreadable: {exc.strerror or exc}", source=source) from None
    if _depth(text) > MAX_DEPTH:
        raise InputError("nested too deeply", source=source, allowed=f"at most {MAX_DEPTH} levels")
    try:
        data = json.loads(text)
    except ValueError as exc:  # JSONDecodeError
        raise InputError(f"malformed JSON: {exc}", source=source) from None
    check_shape(data, shape, source)
    return data


def _name(shape: Any) -> str:
    names = {str: "a string", int: "an integer", float: "a number", bool: "true or false"}
    names[dict] = "an object"
    if shape in names:
        return names[shape]
    if isinstance(shape, dict | MapOf):
        return "an object"
    if isinstance(shape, list):
        return "an array"
    if isinstance(shape, OneOf):
        return " or ".join(_name(s) for s in shape.shapes)
    return "null" if shape is None else "a value"


def _matches_scalar(value: Any, shape: Any) -> bool:
    if shape is None:
        return value is None
    if shape is bool:
        return isinstance(value, bool)
    if shape is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if shape is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    return isinstance(value, shape)


def check_shape(value: Any, shape: Any, source: str, key: str = "") -> None:
    """Raise :class:`InputError` (``source``, dotted ``key`` path) unless ``value`` has
    ``shape`` (see the module docstring)."""
    where = key or "<top>"
    if shape is Any:
        return
    if isinstance(shape, OneOf):
        for option in shape.shapes:
            try:
                check_shape(value, option, source, key)
                return
            except InputError:
                continue
        raise InputError(f"must be {_name(shape)}, got {_brief(value)}", source=source, key=where)
    if isinstance(shape, dict | MapOf):
        if not isinstance(value, dict):
            raise InputError(f"must be an object, got {_brief(value)}", source=source, key=where)
        items = shape.items() if isinstance(shape, dict) else ((k, shape.shape) for k in value)
        for name, sub in items:
            path = f"{key}.{name}" if key else str(name)
            optional = isinstance(sub, Opt)
            if optional and (name not in value or (sub.null and value[name] is None)):
                continue
            if name not in value:
                raise InputError("is required", source=source, key=path)
            check_shape(value[name], sub.shape if optional else sub, source, path)
        return
    if isinstance(shape, list):
        if not isinstance(value, list):
            raise InputError(f"must be an array, got {_brief(value)}", source=source, key=where)
        for i, item in enumerate(value):
            check_shape(item, shape[0], source, f"{key}[{i}]")
        return
    if not _matches_scalar(value, shape):
        raise InputError(f"must be {_name(shape)}, got {_brief(value)}", source=source, key=where)


def _brief(value: Any) -> str:
    """``value`` for a message: short, one line."""
    text = json.dumps(value) if not isinstance(value, float) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
