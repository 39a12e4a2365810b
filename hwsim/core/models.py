"""Typed schemas for every file kind hwsim reads: msgspec models and one error translator.

Each file kind (scene, architecture, technology, sweep, the JSON files ``report`` reads)
declares its shape once as :class:`msgspec.Struct` classes built from the value types
below; :func:`validate` checks a parsed document against it and turns msgspec's
``ValidationError`` into the house's one line, naming the file, the dotted key path and
what is allowed::

    my.toml: formats.voxel_bits: must be an integer, got 'x'
    my.toml: view.azimuth: out of range, got 400 (allowed: -360 .. 360)
    my.toml: render: unknown key 'mdoe' (allowed: mode, ...)

Why msgspec (pyproject.toml): a wrong type, a missing or unknown key and a value out of
range are then properties of the declared model, checked by the library for every key,
not by a hand-written accessor per key (the class of bugs issue 33 closed).

Conventions of the models:

* ``Schema`` (the base) forbids unknown keys and takes keyword fields;
* floats must be finite (:data:`Finite` and the range helpers exclude NaN and
  infinities); ints are never booleans (msgspec's strict mode);
* a TOML key with a hyphen is declared with ``msgspec.field(name="the-key")``;
* inside a union, a pair is a length-bounded list, never a tuple: msgspec 0.22 misreports
  the length of a tuple in a union with a constrained int (``count() | tuple[...]``) and
  may then crash the interpreter.
"""

from __future__ import annotations

import json
import re
import types
import typing
from typing import Annotated, Any

import msgspec
from msgspec import Meta
from msgspec import inspect as mi

from hwsim.core.errors import InputError

__all__ = [
    "Finite",
    "Schema",
    "between",
    "count",
    "finite_at_least",
    "integer",
    "validate",
]

#: The largest magnitude a finite float field takes (excludes inf; NaN fails any bound).
_BIG = 1e300


class Schema(msgspec.Struct, forbid_unknown_fields=True, kw_only=True, frozen=True):
    """Base of every file model: unknown keys refused, fields by keyword."""


#: A finite number (an int is accepted and widened).
Finite = Annotated[float, Meta(ge=-_BIG, le=_BIG)]


def between(lo: float | None = None, hi: float | None = None, *, open_lo: bool = False):
    """A finite float in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``); None: unbounded."""
    low = {"gt" if open_lo else "ge": lo} if lo is not None else {"ge": -_BIG}
    return Annotated[float, Meta(**low, le=_BIG if hi is None else hi)]


def finite_at_least(lo: float, *, open_lo: bool = False):
    """A finite float ``>= lo`` (``> lo`` with ``open_lo``)."""
    return between(lo, None, open_lo=open_lo)


def integer(lo: int | None = None, hi: int | None = None):
    """An int in ``[lo, hi]`` (either bound may be None)."""
    bounds = {k: v for k, v in (("ge", lo), ("le", hi)) if v is not None}
    return Annotated[int, Meta(**bounds)] if bounds else int


def count(hi: int | None = None):
    """A positive int (``1 .. hi``)."""
    return integer(1, hi)


_AT = re.compile(r"^(?P<what>.*?)(?: - at `\$(?P<path>[^`]*)`)?$", re.S)
_TYPE = re.compile(r"^Expected `(?P<want>[^`]+)`, got `(?P<got>[^`]+)`$")
_RANGE = re.compile(r"^Expected `(?P<want>[^`]+)` (?P<op>[<>]=?) (?P<bound>\S+)$")
_UNKNOWN = re.compile(r"^Object contains unknown field `(?P<name>[^`]+)`$")
_MISSING = re.compile(r"^Object missing required field `(?P<name>[^`]+)`$")
_ENUM = re.compile(r"^Invalid enum value (?P<value>.+)$")
_LENGTH = re.compile(r"^Expected `(?P<want>[^`]+)` of length (?P<length>.+)$")
_PATTERN = re.compile(r"^Expected `str` matching regex '(?P<pattern>.*)'$", re.S)

_NAMES = {
    "int": "an integer",
    "float": "a number",
    "str": "a string",
    "bool": "true or false",
    "object": "a table",
    "array": "an array",
    "null": "null",
}


def validate(data: Any, model: Any, source: str, *, prefix: str = "") -> Any:
    """``data`` (a parsed TOML/JSON document) as ``model``; any mismatch is one
    :class:`InputError` naming ``source``, the key path (under ``prefix``) and what is
    allowed."""
    try:
        return msgspec.convert(data, model, strict=True)
    except msgspec.ValidationError as exc:
        raise _translate(str(exc), data, model, source, prefix) from None


def _translate(text: str, data: Any, model: Any, source: str, prefix: str) -> InputError:
    match = _AT.match(text)
    what, path = match["what"], match["path"] or ""
    if "[...]" in path:  # msgspec does not name a dict's key: find the entry that fails
        return _in_mapping(path, data, model, source, prefix) or InputError(
            f"invalid: {what}", source=source, key=_join(prefix, _split(path)) or "<top>"
        )
    parts = _split(path)
    here = _join(prefix, parts)
    if m := _UNKNOWN.match(what):
        info = _info_at(model, parts)
        names = [f.encode_name for f in getattr(info, "fields", ())]
        key = _join(here, [m["name"]]) if here else m["name"]
        allowed = ", ".join(names) if names else None
        return InputError(f"unknown key {m['name']!r}", source=source, key=key, allowed=allowed)
    if m := _MISSING.match(what):
        key = _join(here, [m["name"]]) if here else m["name"]
        return InputError("is required", source=source, key=key)
    value = _value_at(data, parts)
    key = here or "<top>"
    if m := _TYPE.match(what):
        want = " or ".join(_NAMES.get(w.strip(), w.strip()) for w in m["want"].split("|"))
        allowed = _choices(model, parts) or _allowed(_info_at(model, parts))
        return InputError(
            f"must be {want}, got {_brief(value)}", source=source, key=key, allowed=allowed
        )
    if _ENUM.match(what):
        allowed = _choices(model, parts) or _allowed(_info_at(model, parts))
        return InputError(f"unknown value {_brief(value)}", source=source, key=key, allowed=allowed)
    if _RANGE.match(what):
        allowed = _allowed(_member(_info_at(model, parts), value))
        return InputError(
            f"out of range, got {_brief(value)}", source=source, key=key, allowed=allowed
        )
    if m := _PATTERN.match(what):
        return InputError(
            f"invalid {_brief(value)}", source=source, key=key, allowed=f"matching {m['pattern']}"
        )
    if m := _LENGTH.match(what):
        want = _NAMES.get(m["want"], m["want"])
        allowed = _allowed(_member(_info_at(model, parts), value))
        return InputError(
            f"must be {want} of length {m['length']}", source=source, key=key, allowed=allowed
        )
    return InputError(f"invalid: {what}", source=source, key=key)


def _in_mapping(path: str, data: Any, model: Any, source: str, prefix: str) -> InputError | None:
    """The error inside the first failing value of the table at ``path``'s first
    ``[...]``, re-validated alone so that its key is named."""
    head = _split(path.split("[...]", 1)[0])
    table = _value_at(data, head)
    value_type = _annotation_at(model, head)
    args = typing.get_args(_strip(value_type))
    if not isinstance(table, dict) or len(args) != 2:
        return None
    for name, item in table.items():
        try:
            msgspec.convert(item, args[1], strict=True)
        except msgspec.ValidationError as exc:
            return _translate(str(exc), item, args[1], source, _join(prefix, [*head, str(name)]))
    return None


def _strip(annotation: Any) -> Any:
    """``annotation`` without ``Annotated``, ``| None`` and ``| UnsetType``."""
    while True:
        origin = typing.get_origin(annotation)
        if origin is Annotated:
            annotation = typing.get_args(annotation)[0]
        elif origin in (typing.Union, types.UnionType):
            members = [a for a in typing.get_args(annotation) if a not in _ABSENT]
            if len(members) != 1:
                return annotation
            annotation = members[0]
        else:
            return annotation


#: Union members that stand for an absent key, not for a type a file can hold.
_ABSENT = (type(None), msgspec.UnsetType)


def _choices(model: Any, parts: list[str | int]) -> str | None:
    """The ``Literal`` values declared at ``parts`` (a union's Literal member included),
    in their declared order (msgspec's type info holds them as an unordered set)."""
    annotation = _strip(_annotation_at(model, parts))
    members = (
        typing.get_args(annotation)
        if typing.get_origin(annotation)
        in (
            typing.Union,
            types.UnionType,
        )
        else (annotation,)
    )
    for member in members:
        member = _strip(member)
        if typing.get_origin(member) is typing.Literal:
            return ", ".join(str(v) for v in typing.get_args(member))
    return None


def _annotation_at(model: Any, parts: list[str | int]) -> Any:
    """The declared type (a Python annotation) of the value at ``parts``."""
    annotation = model
    for part in parts:
        annotation = _strip(annotation)
        if isinstance(annotation, type) and issubclass(annotation, msgspec.Struct):
            fields = {f.encode_name: f.type for f in msgspec.structs.fields(annotation)}
            annotation = fields.get(part)
        else:
            args = typing.get_args(annotation)
            origin = typing.get_origin(annotation)
            if origin is dict and len(args) == 2:
                annotation = args[1]
            elif origin is tuple and args and args[-1] is not Ellipsis and isinstance(part, int):
                annotation = args[part] if part < len(args) else None
            elif args:
                annotation = args[0]
            else:
                return None
        if annotation is None:
            return None
    return annotation


def _split(path: str) -> list[str | int]:
    """msgspec's ``.a.b[2].c`` as ``["a", "b", 2, "c"]``."""
    parts: list[str | int] = []
    for name, index in re.findall(r"\.([^.\[]+)|\[(\d+)\]", path):
        parts.append(int(index) if index else name)
    return parts


def _join(prefix: str, parts: list[str | int]) -> str:
    text = prefix
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _value_at(data: Any, parts: list[str | int]) -> Any:
    for part in parts:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def _info_at(model: Any, parts: list[str | int]) -> Any:
    """The msgspec type info of the value at ``parts`` inside ``model`` (None: unknown)."""
    info = mi.type_info(model)
    for part in parts:
        info = _step(info, part)
        if info is None:
            return None
    return _unwrap(info)


def _unwrap(info: Any) -> Any:
    """A union's non-null member (the first struct, dict or list one), else the info."""
    if isinstance(info, mi.UnionType):
        members = [t for t in info.types if not isinstance(t, mi.NoneType)]
        return members[0] if len(members) == 1 else info
    return info


def _step(info: Any, part: str | int) -> Any:
    info = _unwrap(info)
    if isinstance(info, mi.UnionType):
        for member in info.types:
            found = _step(member, part)
            if found is not None:
                return found
        return None
    if isinstance(info, mi.StructType) and isinstance(part, str):
        return next((f.type for f in info.fields if f.encode_name == part), None)
    if isinstance(info, mi.DictType) and isinstance(part, str):
        return info.value_type
    if isinstance(info, mi.ListType | mi.TupleType | mi.VarTupleType) and isinstance(part, int):
        if isinstance(info, mi.TupleType):
            return info.item_types[part] if part < len(info.item_types) else None
        return info.item_type
    return None


def _member(info: Any, value: Any) -> Any:
    """The member of a union (``N | [W, H]``) a value out of range or of the wrong length
    was read as: the one of its JSON kind; ``info`` itself if not a union."""
    if not isinstance(info, mi.UnionType):
        return info
    kinds = {
        int: mi.IntType | mi.FloatType,
        float: mi.FloatType,
        str: mi.StrType,
        list: mi.ListType | mi.TupleType | mi.VarTupleType,
        dict: mi.DictType | mi.StructType,
    }
    kind = kinds.get(type(value))
    found = [t for t in info.types if kind is not None and isinstance(t, kind)]
    return found[0] if len(found) == 1 else info


def _allowed(info: Any) -> str | None:
    """What a range or choice allows, from the model's declared constraints."""
    if isinstance(info, mi.LiteralType):
        return ", ".join(str(v) for v in info.values)
    if isinstance(info, mi.EnumType):
        return ", ".join(str(m.value) for m in info.cls)
    if isinstance(info, mi.IntType | mi.FloatType):
        lo = info.ge if info.ge is not None else info.gt
        hi = info.le if info.le is not None else info.lt
        lo_text = None if lo is None or abs(lo) >= _BIG else f"{lo:g}"
        hi_text = None if hi is None or abs(hi) >= _BIG else f"{hi:g}"
        if isinstance(info, mi.FloatType) and lo_text is None and hi_text is None:
            return "a finite number"
        if lo_text and hi_text:
            return f"{lo_text}{' (exclusive)' if info.gt is not None else ''} .. {hi_text}"
        if lo_text:
            return f"{'>' if info.gt is not None else '>='} {lo_text}"
        if hi_text:
            return f"{'<' if info.lt is not None else '<='} {hi_text}"
    if isinstance(info, mi.StrType) and info.pattern:
        return f"matching {info.pattern}"
    if isinstance(info, mi.ListType | mi.VarTupleType | mi.StrType):
        lo, hi = info.min_length, info.max_length
        if lo is not None or hi is not None:
            return f"length {lo or 0} .. {hi if hi is not None else 'any'}"
    return None


def _brief(value: Any) -> str:
    """``value`` for a message: short, one line."""
    try:
        text = repr(value) if isinstance(value, float | str) else json.dumps(value, default=str)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
