"""Sweep files: a ``[sweep]`` table of parameter lists whose product is the set of runs.

# Ref: shared/docs/design.md section 9 (the sweep file) and section 8 (one row per run,
#      keyed by a hash of scene + architecture + overrides + fidelity + code version).

Every value is checked when the file is read, so a typo fails the whole sweep at once
with one line naming the file and key, instead of failing every run later::

    sweep.toml: sweep.pipelines[1]: out of range, got 0 (allowed: 1 .. 4096)

The file's shape (which parameters, each a non-empty list of values of which type and
range) is one msgspec model, :class:`SweepFile`; what a type cannot say (a scene, phantom,
volume, architecture or technology that exists, a format key the machine has) is checked
after it.

A run is plain data (:class:`RunSpec`, picklable for Dask workers): the parameters
that vary, plus the folder relative paths are resolved against.  :func:`build_run`
turns it into the scene and the architecture config the fidelity ladder renders.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec
from msgspec import UNSET, Meta, UnsetType

from hwsim import __version__
from hwsim.core.config import read_toml
from hwsim.core.errors import InputError
from hwsim.core.models import Finite, Schema, between, count, validate
from hwsim.run.render_request import FIDELITIES
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import MAX_IMAGE, MODES, Scene, VolumeSpec, load_scene

__all__ = [
    "SCHEMA",
    "PARAMETERS",
    "MAX_RUNS",
    "RunProduct",
    "RunSpec",
    "Sweep",
    "SweepFile",
    "load_sweep",
    "parse_sweep",
    "build_run",
    "run_key",
    "technology_of",
    "code_version",
]

SCHEMA = 1


def _values(item: Any) -> Any:
    """A parameter's values: a non-empty list of ``item``."""
    return Annotated[list[item], Meta(min_length=1)]


_SIZE = count(MAX_IMAGE)
#: ``image``: N (square) or [W, H].  (A list, not a tuple: msgspec 0.22 misreports, and
#: may crash on, a tuple of the wrong length inside a union with a constrained int.)
_IMAGE = _SIZE | Annotated[list[_SIZE], Meta(min_length=2, max_length=2)]


class SweepTable(Schema):
    """The ``[sweep]`` table: each parameter the non-empty list of values it takes, in
    the order the product iterates them (the last varies fastest)."""

    scene: _values(str) | UnsetType = UNSET  # a built-in scene or a FILE.toml
    phantom: _values(str) | UnsetType = UNSET  # NAME[:k=v,...]
    volume: _values(str) | UnsetType = UNSET  # a volume file beside the sweep file
    arch: _values(str) | UnsetType = UNSET  # a built-in architecture or a FILE.toml
    fidelity: _values(Literal[FIDELITIES]) | UnsetType = UNSET
    mode: _values(Literal[MODES]) | UnsetType = UNSET
    view: _values(tuple[between(-360, 360), between(-90, 90)]) | UnsetType = UNSET
    image: _values(_IMAGE) | UnsetType = UNSET
    pipelines: _values(count(4096)) | UnsetType = UNSET
    clock_hz: _values(between(1.0, 10e9)) | UnsetType = UNSET
    timing_only: _values(bool) | UnsetType = UNSET
    technology: _values(str) | UnsetType = UNSET  # a built-in technology or a FILE.toml
    #: Architecture format overrides: ``formats.<unit>.<field> = [values]``.
    formats: dict[str, dict[str, _values(int | Finite | str)]] = {}


class SweepFile(Schema):
    """A sweep TOML file."""

    sweep: SweepTable
    schema: Literal[1] = SCHEMA


#: Parameters a ``[sweep]`` table may list, in the order the product iterates them.
#: ``formats.<unit>.<field>`` keys (architecture format overrides) come on top.
PARAMETERS = tuple(f.name for f in msgspec.structs.fields(SweepTable) if f.name != "formats")
_ARCH_OVERRIDES = ("pipelines", "clock_hz")
#: The most runs one sweep file may describe (the product of its lists' lengths).
MAX_RUNS = 10**7


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: the parameter values (JSON-able) and the sweep file's folder."""

    params: tuple[tuple[str, Any], ...]
    base_dir: str

    @property
    def values(self) -> dict[str, Any]:
        return dict(self.params)

    def label(self) -> str:
        """Short human description, e.g. ``arch=cube4 fidelity=functional pipelines=2``."""
        return " ".join(f"{k}={_short(v)}" for k, v in self.params)


class RunProduct(Sequence[RunSpec]):
    """The runs of a sweep, made one at a time: the product of the axes' lists in file
    order (the last axis varies fastest), indexable without building the others."""

    def __init__(self, axes: dict[str, list[Any]], base_dir: str) -> None:
        self._names = list(axes)
        self._lists = [axes[n] for n in self._names]
        self._base = base_dir

    def __len__(self) -> int:
        return math.prod(len(v) for v in self._lists)

    def _run(self, combo: tuple[Any, ...]) -> RunSpec:
        return RunSpec(tuple(zip(self._names, combo, strict=True)), self._base)

    def __iter__(self) -> Iterator[RunSpec]:
        return (self._run(combo) for combo in itertools.product(*self._lists))

    def __getitem__(self, index):  # type: ignore[override]
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        n = len(self)
        if not -n <= index < n:
            raise IndexError(index)
        index %= n
        combo = []
        for values in reversed(self._lists):  # mixed radix, last axis fastest
            index, digit = divmod(index, len(values))
            combo.append(values[digit])
        return self._run(tuple(reversed(combo)))


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file: its source, its axes and its runs (made lazily)."""

    source: str
    axes: dict[str, list[Any]]
    base_dir: str

    @property
    def runs(self) -> RunProduct:
        """Every run of the product, in order, made as it is read."""
        return RunProduct(self.axes, self.base_dir)

    @property
    def size(self) -> int:
        """How many runs the product has, from the lists' lengths."""
        return math.prod(len(v) for v in self.axes.values())


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep TOML file."""
    path = Path(path)
    return parse_sweep(read_toml(path), source=str(path), base_dir=path.resolve().parent)


def parse_sweep(data: dict[str, Any], *, source: str, base_dir: str | Path) -> Sweep:
    """Validate parsed sweep TOML; every run is built once here so bad values fail early."""
    table = validate(data, SweepFile, source).sweep
    base = str(Path(base_dir))
    axes: dict[str, list[Any]] = {}
    for name in PARAMETERS:
        values = getattr(table, name)
        if values is not UNSET:
            for i, value in enumerate(values):
                _check(name, value, source, f"sweep.{name}[{i}]", base)
            axes[name] = [_plain(name, v) for v in values]
    for unit, fields in table.formats.items():
        for field, values in fields.items():
            _check_format(f"formats.{unit}.{field}", source)
            axes[f"formats.{unit}.{field}"] = list(values)
    if "phantom" in axes and "volume" in axes:
        raise InputError("give phantom or volume, not both", source=source, key="sweep.volume")
    sweep = Sweep(source=source, axes=axes, base_dir=base)
    if sweep.size > MAX_RUNS:
        sizes = " x ".join(str(len(v)) for v in axes.values())
        raise InputError(
            f"the product of the lists has {sweep.size} runs ({sizes})",
            source=source,
            key="sweep",
            allowed=f"at most {MAX_RUNS} runs",
        )
    for run in _machine_runs(axes, base):  # each distinct machine once
        try:
            build_run(run)
        except InputError as exc:
            if not (exc.key or "").startswith("formats"):
                raise  # an architecture file's own error names that file and key
            formats = [k for k, _ in run.params if k.startswith("formats.")]
            key = exc.key if exc.key in formats else formats[0]
            raise InputError(
                exc.message, source=source, key=f"sweep.{key}", allowed=exc.allowed
            ) from None
    return sweep


def _machine_runs(axes: dict[str, list[Any]], base: str) -> Iterator[RunSpec]:
    """One run per distinct machine (architecture and its overrides), the other axes at
    their first value: what the file's machines are checked with."""
    machine = {n: v for n, v in axes.items() if _is_machine(n)}
    seen: set[tuple] = set()
    for combo in itertools.product(*machine.values()):
        chosen = dict(zip(machine, combo, strict=True))
        params = tuple((n, chosen[n] if n in chosen else v[0]) for n, v in axes.items())
        token = tuple((n, json.dumps(v)) for n, v in chosen.items())
        if token not in seen:
            seen.add(token)
            yield RunSpec(params, base)


def build_run(run: RunSpec) -> tuple[Scene, ArchConfig | None, str, dict[str, Any]]:
    """The scene, architecture (``None``: golden's ideal rays), fidelity and overrides."""
    from hwsim.run.fidelity import DEFAULT_ARCH, resolve_arch

    p = run.values
    base = Path(run.base_dir)
    scene_ref = p.get("scene", "head")
    if scene_ref.endswith(".toml") or "/" in scene_ref:
        scene = load_scene(base / scene_ref)
    else:
        scene = load_scene(scene_ref)
    if "phantom" in p:
        from hwsim.volumes import parse_phantom_spec

        name, params = parse_phantom_spec(p["phantom"])
        scene = scene.replace(volume=VolumeSpec(phantom=name, params=tuple(sorted(params.items()))))
    if "volume" in p:
        scene = scene.replace(volume=VolumeSpec(path=str((base / p["volume"]).resolve())))
    render, view = scene.render, scene.view
    if "mode" in p:
        render = dataclasses.replace(render, mode=p["mode"])
    if "view" in p:
        view = dataclasses.replace(view, azimuth=p["view"][0], elevation=p["view"][1])
    if "image" in p:
        view = dataclasses.replace(view, width=p["image"][0], height=p["image"][1])
    scene = scene.replace(render=render, view=view)
    fidelity = p.get("fidelity", "functional")
    overrides = {k: v for k, v in p.items() if k in _ARCH_OVERRIDES or k.startswith("formats.")}
    arch_ref = p.get("arch")
    if arch_ref is None and (fidelity != "golden" or overrides):
        arch_ref = DEFAULT_ARCH
    arch = None
    if arch_ref is not None:
        is_file = arch_ref.endswith(".toml") or "/" in arch_ref
        arch = resolve_arch(str(base / arch_ref) if is_file else arch_ref)
        arch = apply_overrides(arch, overrides)
    return scene, arch, fidelity, overrides


def apply_overrides(arch: ArchConfig, overrides: dict[str, Any]) -> ArchConfig:
    """A copy of ``arch`` with ``pipelines``, ``clock_hz`` and ``formats.*`` replaced.

    Format keys are checked by building the machine's datapath (the models layer owns
    their meaning and ranges).
    """
    if not overrides:
        return arch
    formats = _flatten(arch.formats, "")
    fields: dict[str, Any] = {}
    for key, value in overrides.items():
        if key.startswith("formats."):
            formats[key.removeprefix("formats.")] = value
        else:
            fields[key] = value
    arch = dataclasses.replace(arch, formats=formats, **fields)
    if any(k.startswith("formats.") for k in overrides):
        from models.datapath import Datapath

        Datapath.from_arch(arch, 0)
    return arch


def code_version() -> str:
    """``<version>+<hash>``: the package version and a hash of every source file."""
    return _code_version()


@cache
def _code_version() -> str:
    import hwsim
    import models

    digest = hashlib.sha256()
    for package in (hwsim, models):
        root = Path(package.__file__).parent
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".toml") and "__pycache__" not in path.parts:
                digest.update(str(path.relative_to(root.parent)).encode())
                digest.update(path.read_bytes())
    return f"{__version__}+{digest.hexdigest()[:12]}"


def technology_of(run: RunSpec) -> str | None:
    """The run's ``technology`` (a file relative to the sweep file's folder), or None."""
    value = run.values.get("technology")
    if value is None:
        return None
    return str(Path(run.base_dir) / value) if value.endswith(".toml") else value


def run_key(run: RunSpec) -> str:
    """SHA-256 of the resolved scene, architecture, overrides, fidelity and code version."""
    scene, arch, fidelity, overrides = build_run(run)
    payload = {
        "scene": scene.to_dict(),
        "arch": arch.to_dict() if arch is not None else None,
        "overrides": overrides,
        "fidelity": fidelity,
        "code": code_version(),
    }
    if run.values.get("timing_only"):  # a timed frame without its image is another run
        payload["timing_only"] = True
    if run.values.get("technology"):  # the same frame priced in another node
        payload["technology"] = technology_of(run)
    text = json.dumps(payload, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


# --------------------------------------------------------------------------- checking


def _plain(name: str, value: Any) -> Any:
    """A validated value as a run holds it (JSON-able): ``[az, el]``, ``[W, H]``."""
    if name == "image" and isinstance(value, int):
        return [value, value]
    return list(value) if isinstance(value, tuple) else value


def _check(name: str, value: Any, source: str, key: str, base: str) -> None:
    """What the model cannot say: the scene, phantom, volume, architecture or technology
    a value names exists (each error names the sweep file and ``key``)."""
    from hwsim.run.fidelity import builtin_archs

    if name == "scene":
        try:
            load_scene(Path(base) / value if value.endswith(".toml") or "/" in value else value)
        except InputError as exc:
            raise InputError(str(exc), source=source, key=key) from None
    elif name == "phantom":
        from hwsim.volumes import parse_phantom_spec

        try:
            parse_phantom_spec(value)
        except InputError as exc:
            raise InputError(exc.message, source=source, key=key, allowed=exc.allowed) from None
    elif name == "volume":  # read through input_file: recorded as an input of the command
        from hwsim.core.paths import input_file

        try:
            input_file(Path(base) / value, folder=True)  # a folder: a DICOM series
        except InputError as exc:
            raise InputError(f"volume {value!r}: {exc.message}", source=source, key=key) from None
    elif name == "arch":
        is_file = value.endswith(".toml") or "/" in value
        if not is_file and value not in builtin_archs():
            allowed = ", ".join(builtin_archs()) + " or a FILE.toml"
            raise InputError(
                f"unknown architecture {value!r}", source=source, key=key, allowed=allowed
            )
    elif name == "technology":
        from hwsim.energy import load_technology

        try:
            load_technology(str(Path(base) / value) if value.endswith(".toml") else value)
        except InputError as exc:
            raise InputError(exc.message, source=source, key=key, allowed=exc.allowed) from None


def _check_format(name: str, source: str) -> None:
    """``formats.<unit>.<field>``: a field of a unit the datapath has."""
    from models.datapath import UNIT_CONFIGS

    unit, _, field = name.removeprefix("formats.").partition(".")
    known = (
        {f.name for f in dataclasses.fields(UNIT_CONFIGS[unit])} if unit in UNIT_CONFIGS else set()
    )
    if not (unit == "voxel" and field == "bits") and field not in known:
        allowed = ", ".join(
            f"formats.{u}.{f.name}" for u, c in UNIT_CONFIGS.items() for f in dataclasses.fields(c)
        )
        raise InputError("unknown format key", source=source, key=f"sweep.{name}", allowed=allowed)


def _flatten(table: dict[str, Any], prefix: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else k
        if isinstance(v, dict):
            out.update(_flatten(v, name))
        else:
            out[name] = v
    return out


def _is_machine(name: str) -> bool:
    """Whether a parameter defines a run's machine (architecture and its overrides)."""
    return name in _ARCH_OVERRIDES or name == "arch" or name.startswith("formats.")


def _short(value: Any) -> str:
    if isinstance(value, list):  # image [W, H] -> WxH, view [az, el] -> az,el
        sep = "x" if all(isinstance(v, int) for v in value) else ","
        return sep.join(_short(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)
