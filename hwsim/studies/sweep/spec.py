"""Sweep files: a ``[sweep]`` table of parameter lists whose product is the set of runs.

# Ref: shared/docs/design.md section 9 (the sweep file) and section 8 (one row per run,
#      keyed by a hash of scene + architecture + overrides + fidelity + code version).

Every value is checked when the file is read, so a typo fails the whole sweep at once
with one line naming the file and key, instead of failing every run later::

    sweep.toml: sweep.pipelines[1]: 0 is out of range (allowed: 1 .. 4096)

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
from typing import Any

from hwsim import __version__
from hwsim.core.config import Table, check_number, read_toml
from hwsim.core.errors import InputError
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import MAX_IMAGE, MODES, Scene, VolumeSpec, load_scene

__all__ = [
    "SCHEMA",
    "PARAMETERS",
    "MAX_RUNS",
    "RunProduct",
    "RunSpec",
    "Sweep",
    "load_sweep",
    "parse_sweep",
    "build_run",
    "run_key",
    "technology_of",
    "code_version",
]

SCHEMA = 1
#: Parameters a ``[sweep]`` table may list, in the order the product iterates them.
#: ``formats.<unit>.<field>`` keys (architecture format overrides) come on top.
PARAMETERS = (
    "scene",
    "phantom",
    "volume",
    "arch",
    "fidelity",
    "mode",
    "view",
    "image",
    "pipelines",
    "clock_hz",
    "timing_only",
    "technology",
)
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
    top = Table(data, source)
    top.schema(SCHEMA)
    table = top.table("sweep", required=True)
    top.finish()
    formats = table.table("formats").data  # <unit>.<field> = [values]
    raw = {k: v for k, v in table.data.items() if k != "formats"}
    axes: dict[str, list[Any]] = {}
    for name in raw:
        if name not in PARAMETERS:
            allowed = ", ".join(PARAMETERS) + ", formats.<unit>.<field>"
            raise table.error(name, "unknown sweep parameter", allowed)
    base = str(Path(base_dir))
    for name in PARAMETERS:
        if name in raw:
            axes[name] = [
                _check(name, v, source, f"sweep.{name}[{i}]", base)
                for i, v in enumerate(_as_list(raw[name], source, f"sweep.{name}"))
            ]
    for key, values in _flatten(formats, "formats").items():
        axes[key] = [
            _check_format(key, v, source, f"sweep.{key}[{i}]")
            for i, v in enumerate(_as_list(values, source, f"sweep.{key}"))
        ]
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


def _as_list(value: Any, source: str, key: str) -> list[Any]:
    if not isinstance(value, list) or not value:
        raise InputError(f"must be a non-empty list, got {value!r}", source=source, key=key)
    return value


def _check(name: str, value: Any, source: str, key: str, base: str) -> Any:
    from hwsim.run.fidelity import FIDELITIES, builtin_archs

    if name in ("scene", "phantom", "volume", "arch") and not isinstance(value, str):
        raise InputError(f"must be a string, got {value!r}", source=source, key=key)
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
    elif name == "volume":
        if not (Path(base) / value).exists():
            raise InputError(f"no such volume {value!r}", source=source, key=key)
    elif name == "arch":
        is_file = value.endswith(".toml") or "/" in value
        if not is_file and value not in builtin_archs():
            allowed = ", ".join(builtin_archs()) + " or a FILE.toml"
            raise InputError(
                f"unknown architecture {value!r}", source=source, key=key, allowed=allowed
            )
    elif name == "technology":
        from hwsim.energy import load_technology

        if not isinstance(value, str):
            raise InputError(f"must be a string, got {value!r}", source=source, key=key)
        try:
            load_technology(str(Path(base) / value) if value.endswith(".toml") else value)
        except InputError as exc:
            raise InputError(exc.message, source=source, key=key, allowed=exc.allowed) from None
    elif name == "timing_only":
        if not isinstance(value, bool):
            raise InputError(f"must be true or false, got {value!r}", source=source, key=key)
    elif name == "fidelity":
        if value not in FIDELITIES:
            raise InputError(
                f"unknown fidelity {value!r}", source=source, key=key, allowed=", ".join(FIDELITIES)
            )
    elif name == "mode":
        if value not in MODES:
            raise InputError(
                f"unknown mode {value!r}", source=source, key=key, allowed=", ".join(MODES)
            )
    elif name == "view":
        if not isinstance(value, list) or len(value) != 2:
            raise InputError(f"must be [azimuth, elevation], got {value!r}", source=source, key=key)
        return [
            check_number(value[0], source, f"{key}[0]", -360, 360),
            check_number(value[1], source, f"{key}[1]", -90, 90),
        ]
    elif name == "image":
        pair = value if isinstance(value, list) else [value, value]
        if len(pair) != 2 or any(isinstance(v, bool) or not isinstance(v, int) for v in pair):
            raise InputError(f"must be N or [W, H] integers, got {value!r}", source=source, key=key)
        for v in pair:
            if not 1 <= v <= MAX_IMAGE:
                raise InputError(
                    f"{v} is out of range", source=source, key=key, allowed=f"1 .. {MAX_IMAGE}"
                )
        return list(pair)
    elif name == "pipelines":
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 4096:
            raise InputError(
                f"{value!r} is out of range", source=source, key=key, allowed="1 .. 4096"
            )
    elif name == "clock_hz":
        return check_number(value, source, key, 1.0, 10e9)
    return value


def _check_format(name: str, value: Any, source: str, key: str) -> Any:
    from models.datapath import UNIT_CONFIGS

    unit, _, field = name.removeprefix("formats.").partition(".")
    known = (
        {f.name for f in dataclasses.fields(UNIT_CONFIGS[unit])} if unit in UNIT_CONFIGS else set()
    )
    if not (unit == "voxel" and field == "bits") and field not in known:
        allowed = ", ".join(
            f"formats.{u}.{f.name}" for u, c in UNIT_CONFIGS.items() for f in dataclasses.fields(c)
        )
        raise InputError(
            "unknown format key",
            source=source,
            key=name.replace("formats.", "sweep.formats.", 1),
            allowed=allowed,
        )
    if not isinstance(value, (int, float, str)) or isinstance(value, bool):
        raise InputError(f"must be a number or a name, got {value!r}", source=source, key=key)
    return value


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
