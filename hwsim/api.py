"""The Python API: what ``hwsim render``, ``sweep`` and ``trade`` do, as functions.

``import hwsim`` re-exports these names (``hwsim.render``, ``hwsim.load_scene``, ...);
docs/api.md is their reference.  Each function is a thin layer over the library calls
the command line makes (:mod:`hwsim.spec.overrides` for the scene overrides,
:func:`hwsim.run.fidelity.render`, :func:`hwsim.run.output.write_render`, the sweep runner and the
ladder trade), so a script and the CLI produce the same images, stats and files.  Bad
input raises :class:`~hwsim.core.errors.InputError`, one line naming the key: the keyword's
name where the CLI's would name its flag (``view``, not ``--view``).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hwsim.core.errors import InputError
from hwsim.studies.sweep.runner import SweepSummary as SweepResult

if TYPE_CHECKING:
    from hwsim.run.fidelity import RenderRun
    from hwsim.spec.arch import ArchConfig
    from hwsim.spec.scene import Scene
    from hwsim.volumes.volume import Volume

__all__ = [
    "Run",
    "SweepResult",
    "load_scene",
    "load_volume",
    "render",
    "archs",
    "arch",
    "sweep",
    "trade",
]

#: Keywords of :func:`load_scene`: the ``hwsim render`` scene flags.
SCENE_OVERRIDES = (
    "volume",
    "phantom",
    "shape",
    "dtype",
    "mode",
    "view",
    "image",
    "projection",
    "transfer",
)
#: Keywords of :func:`render` besides ``fidelity`` and ``arch`` (hwsim.run.fidelity.render's,
#: plus ``threads`` and ``max_memory``, which the CLI sets around a render).
RENDER_OPTIONS = (
    "sampling",
    "volume",
    "progress",
    "trace",
    "simulator",
    "extend",
    "timing_only",
    "technology",
    "workers",
    "scheduler",
    "bands",
    "elaborate_all",
    "steady_state",
    "threads",
    "max_memory",
)
#: Keywords of :func:`load_volume` for a file (a phantom takes its own parameters).
FILE_OPTIONS = ("shape", "dtype", "byte_order", "header_bytes", "spacing")
#: Architecture fields :func:`arch` may override (as a sweep file does).
ARCH_OVERRIDES = ("pipelines", "clock_hz", "formats")


#: True while the command line calls the API: its errors keep naming flags (``--view``).
_naming_flags: contextvars.ContextVar[bool] = contextvars.ContextVar("naming_flags", default=False)


@contextlib.contextmanager
def naming_flags() -> Iterator[None]:
    """Inside the block, API errors name the command line's flags (the CLI's calls)."""
    token = _naming_flags.set(True)
    try:
        yield
    finally:
        _naming_flags.reset(token)


def _api_errors(fn: Callable) -> Callable:
    """Name the keyword, not the CLI flag, in an InputError (``--view`` -> ``view``)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except InputError as exc:
            if _naming_flags.get():
                raise
            key, source = _keyword(exc.key), _keyword(exc.source)
            if (key, source) == (exc.key, exc.source):
                raise
            new = type(exc)(exc.message, source=source, key=key, allowed=exc.allowed)
            raise new.with_traceback(exc.__traceback__) from None

    return wrapper


def _keyword(flag: str | None) -> str | None:
    """``--timing-only`` -> ``timing_only`` (``--shape/--dtype`` -> ``shape/dtype``)."""
    if not flag or not flag.startswith("--"):
        return flag
    return "/".join(k.removeprefix("--").replace("-", "_") for k in flag.split("/"))


def _unknown(keys: Sequence[str], allowed: Sequence[str], what: str, hint: str = "") -> None:
    for key in keys:
        if key not in allowed:
            raise InputError(f"not {what}{hint}", key=key, allowed=", ".join(allowed))


@contextlib.contextmanager
def _budget(max_memory: str | int | None) -> Iterator[None]:
    """``--max-memory``: the memory one process may plan, inside the block."""
    if max_memory is None:
        yield
        return
    from hwsim.core.budget import memory_budget_of, parse_size

    if isinstance(max_memory, bool) or not isinstance(max_memory, (str, int)):
        raise InputError(f"expected e.g. '2G' or bytes, got {max_memory!r}", key="max_memory")
    nbytes = parse_size(max_memory, key="max_memory") if isinstance(max_memory, str) else max_memory
    if nbytes < 1:
        raise InputError(f"{nbytes} is out of range", key="max_memory", allowed=">= 1 byte")
    with memory_budget_of(nbytes):
        yield


def _is_phantom_spec(text: str) -> bool:
    """``head:size=64`` is a phantom, ``ct.nrrd`` or ``data/ct`` a file (or folder)."""
    name = text.strip().partition(":")[0]
    return bool(name) and not Path(text).exists() and not any(c in name for c in "/\\.")


# ----------------------------------------------------------------------------- scenes


@_api_errors
def load_scene(name_or_path: str | Path | Scene | None = None, **overrides: Any) -> Scene:
    """A scene by built-in name (``hwsim scenes``) or TOML file, with the ``hwsim render``
    flags' overrides applied: ``volume`` (a file, DICOM folder or phantom spec such as
    ``"head:size=64"``), ``phantom``, ``shape`` and ``dtype`` (a ``.raw`` file), ``mode``,
    ``view=(azimuth, elevation)``, ``image=N`` or ``(width, height)``, ``projection``,
    ``transfer`` (a preset name such as ``"mr"``, or a transfer ``.toml`` / ``.npy`` file).
    None: the default scene (``head``); a Scene: that scene, overridden."""
    from hwsim.spec.overrides import SceneFlags, apply_overrides
    from hwsim.spec.scene import MODES, PROJECTIONS, Scene
    from hwsim.spec.scene import load_scene as load

    for key in overrides:
        if key not in SCENE_OVERRIDES:
            hint = (
                ": pass it to hwsim.render" if key in ("fidelity", "arch", *RENDER_OPTIONS) else ""
            )
            raise InputError(
                f"not a scene override{hint}", key=key, allowed=", ".join(SCENE_OVERRIDES)
            )
    flags: dict[str, str | None] = {}
    volume = overrides.get("volume")
    if volume is not None:
        if not isinstance(volume, (str, Path)):
            raise InputError(f"expected a path or phantom spec, got {volume!r}", key="volume")
        if isinstance(volume, str) and _is_phantom_spec(volume):
            flags["phantom"] = volume
        else:
            flags["volume"] = str(volume)
    if overrides.get("phantom") is not None:
        if flags:
            raise InputError("give volume or phantom, not both", key="phantom")
        flags["phantom"] = _text(overrides["phantom"], "phantom")
    for key, choices in (("mode", MODES), ("projection", PROJECTIONS)):
        value = overrides.get(key)
        if value is not None and value not in choices:
            raise InputError(f"unknown {key} {value!r}", key=key, allowed=", ".join(choices))
        flags[key] = value
    if overrides.get("dtype") is not None:
        flags["dtype"] = _text(overrides["dtype"], "dtype")
    transfer = overrides.get("transfer")
    if transfer is not None:
        flags["transfer"] = (
            str(transfer) if isinstance(transfer, Path) else _text(transfer, "transfer")
        )
    if overrides.get("shape") is not None:
        flags["shape"] = ",".join(_numbers(overrides["shape"], "shape", 3, int))
    if overrides.get("view") is not None:
        flags["view"] = ",".join(_numbers(overrides["view"], "view", 2, float))
    image = overrides.get("image")
    if image is not None:
        pair = (image, image) if isinstance(image, int) and not isinstance(image, bool) else image
        flags["image"] = "x".join(_numbers(pair, "image", 2, int))
    scene = name_or_path if isinstance(name_or_path, Scene) else load(name_or_path)
    return apply_overrides(scene, SceneFlags(**flags))


def _text(value: Any, key: str) -> str:
    if not isinstance(value, str):
        raise InputError(f"expected a string, got {value!r}", key=key)
    return value


def _numbers(value: Any, key: str, count: int, kind: type) -> list[str]:
    """``count`` numbers of ``kind`` as the flag's text (the CLI's parser checks ranges)."""
    ok = isinstance(value, (tuple, list)) and len(value) == count
    types = (int,) if kind is int else (int, float)
    if not ok or any(isinstance(v, bool) or not isinstance(v, types) for v in value):
        noun = "integers" if kind is int else "numbers"
        raise InputError(f"expected {count} {noun}, got {value!r}", key=key)
    return [repr(kind(v)) for v in value]


@_api_errors
def load_volume(path_or_phantom_spec: str | Path, **options: Any) -> Volume:
    """A volume: a file (``.npy``, NRRD, NIfTI, ``.raw``) or DICOM folder, with ``shape``,
    ``dtype``, ``byte_order``, ``header_bytes`` (``.raw``) and ``spacing`` (z, y, x); or a
    phantom spec (``"head:size=64"``), its parameters also as keywords (``size=64``)."""
    from hwsim.spec.scene import VolumeSpec
    from hwsim.volumes import load_volume as load
    from hwsim.volumes import parse_phantom_spec

    source = path_or_phantom_spec
    if not isinstance(source, (str, Path)):
        raise InputError(f"expected a path or phantom spec, got {source!r}", key="volume")
    spacing = options.pop("spacing", None)
    if spacing is not None:
        spacing = tuple(float(s) for s in _numbers(spacing, "spacing", 3, float))
    if isinstance(source, str) and _is_phantom_spec(source):
        name, params = parse_phantom_spec(source)
        params.update(options)  # checked by the phantom (hwsim.volumes.make_phantom)
        spec = VolumeSpec(phantom=name, params=tuple(params.items()), spacing=spacing)
        return load(spec)
    _unknown(options, FILE_OPTIONS, "a volume file option")
    if options.get("shape") is not None:
        options["shape"] = tuple(int(s) for s in _numbers(options["shape"], "shape", 3, int))
    return load(VolumeSpec(path=str(source), spacing=spacing, **options))


# ----------------------------------------------------------------------------- render


class Run:
    """One render's result: :func:`render` returns it.

    ``image`` (NumPy array: ``H x W x 4`` premultiplied RGBA, or ``H x W`` for mip, minip
    and xray; None when timed without it), ``cycles`` (None for golden), ``samples``,
    ``stats`` (the ``stats.json`` dictionary), :meth:`save`, and ``render_run``, the
    underlying :class:`hwsim.run.fidelity.RenderRun`.
    """

    def __init__(self, render_run: RenderRun, threads: int | None = None) -> None:
        self.render_run = render_run
        self._threads = threads
        self._stats: dict[str, Any] | None = None

    @property
    def image(self) -> Any:
        return self.render_run.image

    @property
    def cycles(self) -> int | None:
        return self.render_run.cycles

    @property
    def samples(self) -> int:
        return self.render_run.samples

    @property
    def fidelity(self) -> str:
        return self.render_run.fidelity

    @property
    def arch(self) -> str | None:
        return self.render_run.arch

    @property
    def stats(self) -> dict[str, Any]:
        """What ``save`` writes as ``stats.json``, as plain JSON types (computed once)."""
        if self._stats is None:
            from hwsim.core.threads import using
            from hwsim.run.output import image_to_rgb8, stats_plain

            with using(self._threads):  # host.frame_threads: the render's count
                stats = stats_plain(self.render_run)
            if self.image is not None:  # how image.png shows it, as write_render adds
                stats["image"].update(image_to_rgb8(self.image)[1])
            self._stats = stats
        return self._stats

    @_api_errors
    def save(self, folder: str | Path) -> dict[str, Path]:
        """Write ``image.png``, ``image.npy``, ``stats.json`` and a timed rung's CSVs into
        ``folder`` (created), as ``hwsim render --out folder`` does; returns the paths by
        kind (``png``, ``npy``, ``stats``, ``throughput``, ...)."""
        from hwsim.core.threads import using
        from hwsim.run.output import write_render

        with using(self._threads):
            return write_render(self.render_run, folder)

    def __repr__(self) -> str:
        r = self.render_run
        cycles = f", cycles={r.cycles}" if r.cycles is not None else ""
        return f"<hwsim.Run {r.scene.name} {r.fidelity}/{r.arch or r.sampling}{cycles}>"


@_api_errors
def render(
    scene: Scene | str | Path,
    fidelity: str = "golden",
    arch: str | Path | ArchConfig | None = None,
    **options: Any,
) -> Run:
    """Render ``scene`` (a Scene, or a name or path for :func:`load_scene`) at
    ``fidelity`` on ``arch`` (a name, file or :func:`arch`); ``options`` are
    :data:`RENDER_OPTIONS` (docs/api.md).  Returns a :class:`Run`."""
    from hwsim.core.threads import using
    from hwsim.run import fidelity as ladder
    from hwsim.spec.scene import Scene

    _unknown(options, RENDER_OPTIONS, "a render option")
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if isinstance(arch, Path):
        arch = str(arch)
    volume = options.get("volume")
    if volume is not None:
        from hwsim.volumes.volume import Volume

        if not isinstance(volume, Volume):
            raise InputError(
                "expected a loaded volume (hwsim.load_volume); a path goes to "
                "hwsim.load_scene(..., volume=PATH)",
                key="volume",
            )
    if options.get("trace") is not None:  # checked before the work starts, never an input
        from hwsim.core.paths import FILE, plan_outputs
        from hwsim.run.output import scene_inputs

        plan_outputs(scene_inputs(scene), [("trace", options["trace"], FILE)])
    threads = options.pop("threads", None)
    max_memory = options.pop("max_memory", None)
    with _budget(max_memory), using(threads):
        run = ladder.render(scene, fidelity=fidelity, arch=arch, **options)
    return Run(run, threads)


# ------------------------------------------------------------------------------ archs


def archs() -> dict[str, ArchConfig]:
    """The built-in machines (``hwsim archs``), name -> :class:`hwsim.spec.arch.ArchConfig`."""
    from hwsim.run.fidelity import builtin_archs

    return builtin_archs()


@_api_errors
def arch(name_or_path: str | Path, **overrides: Any) -> ArchConfig:
    """A built-in machine by name or an architecture file, with ``pipelines``,
    ``clock_hz`` and ``formats={"interp.weight_bits": 6, ...}`` overridden and checked
    as a sweep file's are."""
    from hwsim.run.fidelity import resolve_arch

    _unknown(overrides, ARCH_OVERRIDES, "an architecture override")
    ref = str(name_or_path)
    config = resolve_arch(ref)
    if not overrides:
        return config
    from hwsim.studies.sweep.spec import build_run, parse_sweep

    table: dict[str, Any] = {"arch": [ref], "fidelity": ["functional"]}
    for key in ("pipelines", "clock_hz"):
        if key in overrides:
            table[key] = [overrides[key]]
    formats = overrides.get("formats") or {}
    if not isinstance(formats, dict):
        raise InputError("expected a dict of 'unit.field': value", key="formats")
    nested: dict[str, Any] = {}
    for dotted, value in formats.items():
        unit, _, name = str(dotted).partition(".")
        nested.setdefault(unit, {})[name] = [value]
    if nested:
        table["formats"] = nested
    try:
        sweep_spec = parse_sweep({"schema": 1, "sweep": table}, source="", base_dir=Path.cwd())
    except InputError as exc:  # "sweep.pipelines[0]" -> "pipelines"
        key = (exc.key or "").removeprefix("sweep.").removesuffix("[0]")
        raise InputError(
            exc.message, source=exc.source or None, key=key, allowed=exc.allowed
        ) from None
    return build_run(sweep_spec.runs[0])[1]


# ------------------------------------------------------------------------ sweep, trade


@_api_errors
def sweep(
    spec: str | Path | dict[str, Any],
    *,
    workers: int = 2,
    scheduler: str | None = None,
    db: str | Path = "runs.db",
    out: str | Path | None = None,
    retry_failed: bool = False,
    max_memory: str | int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> SweepResult:
    """Run a sweep (``hwsim sweep``): a sweep TOML file, or its content as a dict (the
    ``[sweep]`` table alone or the whole file); runs already in ``db`` are skipped."""
    from hwsim.core.cluster import check_address, connect, local_client
    from hwsim.core.paths import FILE, FOLDER, plan_outputs
    from hwsim.studies.sweep.db import RunsDB, check_ours
    from hwsim.studies.sweep.runner import run_sweep
    from hwsim.studies.sweep.spec import load_sweep, parse_sweep

    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 256:
        raise InputError(f"{workers!r} is out of range", key="workers", allowed="1 .. 256")
    if isinstance(spec, dict):
        data = spec if "sweep" in spec else {"schema": 1, "sweep": spec}
        plan = parse_sweep(data, source="<sweep dict>", base_dir=Path.cwd())
    else:
        plan = load_sweep(spec)
    spec_file = None if isinstance(spec, dict) else spec
    plan_outputs([("spec", spec_file)], [("db", db, FILE), ("out", out, FOLDER)])
    check_ours(Path(db))
    if scheduler:
        check_address(scheduler)
    keys: set[str] = set()
    with _budget(max_memory), contextlib.ExitStack() as stack:
        if scheduler:  # reached before the database is opened or changed
            client = stack.enter_context(connect(scheduler))
        else:
            client = stack.enter_context(local_client(workers))
        runs_db = stack.enter_context(RunsDB(db))
        summary = run_sweep(
            plan,
            runs_db,
            client,
            out_dir=str(out) if out is not None else None,
            progress=progress,
            retry_failed=retry_failed,
            keys=keys,
        )
        rows = [r for r in runs_db.rows() if r["key"] in keys]
    summary.rows = rows
    return summary


@_api_errors
def trade(
    volumes: str | Path | Sequence[str | Path] = (),
    *,
    archs: str | Sequence[str] | None = None,
    rungs: str | Sequence[str] | None = None,
    image: int = 64,
    size: int = 64,
    extend: bool = False,
    widths: bool = False,
    out: str | Path | None = None,
    max_memory: str | int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict[str, Any]]:
    """The fidelity-ladder trade (``hwsim trade``), or with ``widths`` the bit-width trade
    (``hwsim trade --widths``): its rows; written to ``out`` as the CLI does when given."""
    from hwsim.core.paths import recording_reads
    from hwsim.studies.trade.command import plan_trade

    vols = [str(volumes)] if isinstance(volumes, (str, Path)) else [str(v) for v in volumes]
    machines = [archs] if isinstance(archs, str) else list(archs or [])
    if isinstance(rungs, str):
        rungs = [r.strip() for r in rungs.split(",")]
    for key, value, lo, hi in (("image", image, 8, 1024), ("size", size, 8, 512)):
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            raise InputError(f"{value!r} is out of range", key=key, allowed=f"{lo} .. {hi}")
    with contextlib.ExitStack() as stack:
        if out is not None:  # the command line's plan: no output is an input
            stack.enter_context(recording_reads())
            plan_trade(vols, machines, widths, out)
        stack.enter_context(_budget(max_memory))
        return _trade_rows(vols, machines, rungs, image, size, extend, widths, out, progress)


def _trade_rows(vols, machines, rungs, image, size, extend, widths, out, progress):
    """:func:`trade`'s measurement and files, once its arguments are checked."""
    if widths:
        from hwsim.run.fidelity import resolve_arch
        from hwsim.studies.trade.widths import default_cases, width_trade, write_width_trade

        if len(machines) > 1:
            raise InputError("widths measures one machine", key="archs", allowed="one")
        machine = resolve_arch(machines[0] if machines else "volumepro500")
        rows = width_trade(default_cases(vols, image), machine, progress=progress)
        if out is not None:
            write_width_trade(rows, out)
        return rows
    from hwsim.studies.trade.ladder import ladder_cases, ladder_trade, write_ladder_trade

    cases = ladder_cases(vols, image, size)
    rows = ladder_trade(cases, machines or None, rungs, progress=progress, extend=extend)
    if out is not None:
        write_ladder_trade(rows, out)
    return rows
