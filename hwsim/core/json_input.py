"""Reading back the JSON files hwsim wrote: a depth-limited reader and the base of their
models.

``stats.json``, ``trade.json``, ``figures.json``, ``sweep.json`` and the sweep database's
JSON columns are declared as msgspec models (:class:`Recorded` subclasses, in the module
that reads them) and checked whole at load through :func:`hwsim.core.models.validate`, so a
hand-edited or truncated file is one line naming the file and the key path::

    run/stats.json: volume.shape_zyx[1]: must be an integer, got 'x'
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, validate
from hwsim.core.paths import file_kind

__all__ = ["MAX_DEPTH", "Recorded", "json_depth", "read_json"]

#: Deepest nesting of arrays and objects a JSON input may have (hwsim writes at most ~6).
MAX_DEPTH = 64


class Recorded(Schema, forbid_unknown_fields=False):
    """Base of the models of JSON files hwsim wrote itself and reads back.

    Unlike a hand-written input (a TOML file, where an unknown key is a typo and refused),
    a key the model does not name is ignored here: a newer hwsim adds keys to its outputs,
    and an older ``hwsim report`` must still read them (it reads only the keys its model
    declares).  A declared key of the wrong type is refused as anywhere else.
    """


def json_depth(text: str) -> int:
    """Deepest bracket nesting of JSON ``text`` (brackets inside strings skipped): counted
    before parsing, so that 100 000 nested arrays are one line, never a RecursionError."""
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


def parse_json(text: str, source: str, key: str | None = None) -> Any:
    """``text`` parsed, nested at most :data:`MAX_DEPTH` levels; one :class:`InputError`
    naming ``source`` (and ``key``) otherwise."""
    if json_depth(text) > MAX_DEPTH:
        allowed = f"at most {MAX_DEPTH} levels"
        raise InputError("nested too deeply", source=source, key=key, allowed=allowed)
    try:
        return json.loads(text)
    except ValueError as exc:  # JSONDecodeError
        raise InputError(f"malformed JSON: {exc}", source=source, key=key) from None


def read_json(path: str | Path, model: Any = None, *, source: str | None = None) -> Any:
    """Parse a JSON file and check it against ``model`` (a msgspec type; None: any JSON);
    the parsed document is returned as it is.  Every failure is one :class:`InputError`
    naming the file (``source``, default the path)."""
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
    data = parse_json(text, source)
    if model is not None:
        validate(data, model, source)
    return data
