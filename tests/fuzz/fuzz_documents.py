"""The fuzz tier's shared parts: malformed documents made from valid ones, a TOML writer,
the settings CI runs with and the contract every loader keeps.

A mutation takes a valid built-in document and changes one thing: it replaces the value
at a key path with a value of another type (integers huge and small, floats, NaN, inf,
strings, booleans, lists, nested and empty tables), deletes a key, or adds an unknown one.
The loader under test either returns (and then the values are of their declared types) or
raises :class:`~hwsim.core.errors.InputError` whose one line names the file and a key
path; any other exception fails the test.
"""

from __future__ import annotations

import copy
import json
import math
import os
import types
import typing
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from hwsim.core.errors import InputError

#: CI's bound: 40 examples per property, derandomized (the same documents every run),
#: no per-example deadline (a loader may import a machine model on first use).  A longer
#: local search: ``FUZZ_EXAMPLES=2000 FUZZ_RANDOM=1 pytest -m fuzz``.
FUZZ = settings(
    max_examples=int(os.environ.get("FUZZ_EXAMPLES", "40")),
    deadline=None,
    derandomize=not os.environ.get("FUZZ_RANDOM"),
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

#: Values of every type a file can hold, including the ones that broke loaders before.
ODD_VALUES: list[Any] = [
    0, -1, 1, 7, 2**70, -(2**70), 0.0, -0.5, 1e308, math.nan, math.inf, -math.inf,
    "", "fast", "x" * 300, True, False, [], [1, 2], ["a", "b"], [[1]], [{}],
    {}, {"a": 1}, {"nested": {"deeper": [1]}},
]  # fmt: skip

_TEXT = st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=8)
VALUES = st.one_of(
    st.sampled_from(ODD_VALUES), st.integers(), st.floats(), _TEXT, st.lists(st.integers())
)


@dataclass(frozen=True)
class Mutation:
    kind: str  # "replace", "delete" or "add"
    path: tuple[Any, ...]
    value: Any = None

    def __str__(self) -> str:
        return f"{self.kind} {'.'.join(map(str, self.path))} = {self.value!r}"


def key_paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path of ``doc``: into tables and arrays of tables."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc)
    for key, value in items:
        out.append((*prefix, key))
        if isinstance(value, dict) or (
            isinstance(value, list) and value and all(isinstance(v, dict) for v in value)
        ):
            out += key_paths(value, (*prefix, key))
    return out


def table_paths(doc: Any) -> list[tuple[Any, ...]]:
    """The top level and every table's key path (where an unknown key can be added)."""
    return [()] + [p for p in key_paths(doc) if isinstance(get(doc, p), dict)]


def get(doc: Any, path: tuple[Any, ...]) -> Any:
    for key in path:
        doc = doc[key]
    return doc


#: JSON has null too.
JSON_VALUES = st.one_of(st.none(), VALUES)


@st.composite
def mutations(draw: Any, doc: dict[str, Any], values: st.SearchStrategy = VALUES) -> Mutation:
    kind = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
    if kind == "add":
        path = (*draw(st.sampled_from(table_paths(doc))), "no_such_key")
        return Mutation(kind, path, draw(values))
    path = draw(st.sampled_from(key_paths(doc)))
    return Mutation(kind, path, draw(values) if kind == "replace" else None)


def mutated(doc: dict[str, Any], m: Mutation) -> dict[str, Any]:
    """A copy of ``doc`` with ``m`` applied."""
    out = copy.deepcopy(doc)
    parent = get(out, m.path[:-1])
    if m.kind == "delete":
        del parent[m.path[-1]]
    else:
        parent[m.path[-1]] = copy.deepcopy(m.value)
    return out


def replaced(doc: dict[str, Any], dotted: str, value: Any) -> dict[str, Any]:
    """``doc`` with the value at ``dotted`` (tables created as needed) set to ``value``."""
    out = copy.deepcopy(doc)
    *parents, last = dotted.split(".")
    table = out
    for key in parents:
        table = table.setdefault(key, {})
    table[last] = value
    return out


# --------------------------------------------------------------------------- writing


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        body = ", ".join(f"{json.dumps(str(k))} = {_toml_value(v)}" for k, v in value.items())
        return "{" + body + "}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML for {value!r}")


def toml_dumps(doc: dict[str, Any]) -> str:
    """``doc`` as TOML: one ``"key" = value`` line per top-level key, tables inline (the
    standard library reads TOML but does not write it)."""
    return "".join(f"{json.dumps(str(k))} = {_toml_value(v)}\n" for k, v in doc.items())


def write_toml(folder: Path, name: str, doc: dict[str, Any]) -> Path:
    path = folder / name
    path.write_text(toml_dumps(doc))
    return path


# --------------------------------------------------------------------------- the contract


def loads_or_refuses(load: Any, path: Path, *args: Any) -> Any:
    """``load(path, *args)``: its result, or ``None`` when it raised an
    :class:`InputError` of one line naming ``path``'s file and a key path."""
    try:
        return load(path, *args)
    except InputError as exc:
        text = str(exc)
        assert "\n" not in text, text
        assert path.name in text, f"the message does not name the file: {text}"
        assert exc.key, f"the message names no key path: {text}"
        return None


def check_types(obj: Any, where: str = "") -> None:
    """Every field of dataclass ``obj`` holds a value of its annotated type (its outer
    type: int, float, str, bool, tuple, dict, list, a dataclass, or None when optional)."""
    hints = typing.get_type_hints(type(obj))
    for f in fields(obj):
        value = getattr(obj, f.name)
        assert _fits(value, hints[f.name]), f"{where}{f.name} = {value!r} is not {hints[f.name]}"
        if is_dataclass(value):
            check_types(value, f"{where}{f.name}.")


def _fits(value: Any, hint: Any) -> bool:
    origin = typing.get_origin(hint) or hint
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, h) for h in typing.get_args(hint))
    if hint is type(None):
        return value is None
    if origin is Any or hint is Any:
        return True
    if origin is float:
        return (
            isinstance(value, float | int) and not isinstance(value, bool) and math.isfinite(value)
        )
    if origin is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if isinstance(origin, type):
        return isinstance(value, origin)
    return True  # Literal, TypeVar...: not checked here
