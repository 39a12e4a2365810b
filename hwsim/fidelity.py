"""The fidelity ladder: one entry point, five rungs (design section 3).

``render(scene, fidelity=...)`` loads the scene's volume and transfer function, runs the
requested rung and returns a :class:`RenderRun` holding the image and the raw numbers
``stats.json`` is written from.  A rung that does not model the machine (no family in
the registry, ``models.machines``, has it at that rung) raises
:class:`~hwsim.errors.NotAvailableError` (exit status 2 at the CLI).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.arch import ArchConfig, load_arch_file
from hwsim.budget import SAMPLE_ENV_VAR, require_fits, sample_budget
from hwsim.errors import InputError, NotAvailableError
from hwsim.machine_features import IDEAL, Algorithms, Extension, require_machine
from hwsim.scene import Scene
from hwsim.supervolume import oversize, refuse_supervolume, render_bricks
from hwsim.transfer import TransferFunction, resolve_transfer
from hwsim.volumes import load_volume
from hwsim.volumes.volume import Volume

__all__ = [
    "FIDELITIES",
    "SAMPLINGS",
    "RenderRun",
    "render",
    "builtin_archs",
    "resolve_arch",
]

FIDELITIES = ("golden", "functional", "transaction", "cycle", "rtl")
#: Most workers (and bands) one frame is split across.
MAX_WORKERS = 256
#: The machine a timed rung models when no --arch is given.
DEFAULT_ARCH = "volumepro500"
SAMPLINGS = ("ray", "shear-warp", "shear-image", "slice-parallel")

#: Pipeline units, in order; elaboration keeps only those a scene needs.

Progress = Callable[[int, int], None]


@dataclass(kw_only=True)
class RenderRun:
    """Everything one render produced: image, volume facts and raw counters."""

    scene: Scene
    volume: Volume
    transfer: TransferFunction
    fidelity: str
    arch: str | None
    sampling: str
    image: np.ndarray | None  # None: timed without its image (--timing-only)
    samples: int
    rays: int
    wall_seconds: float
    cycles: int | None = None
    clock_hz: float | None = None
    elaborated_units: list[str] = field(default_factory=list)
    elided_units: list[str] = field(default_factory=list)
    counters: dict[str, Any] = field(default_factory=dict)
    derived: dict[str, Any] = field(default_factory=dict)
    #: What the scene asked outside the machine's declared features (a what-if render).
    extensions: list[dict[str, str]] = field(default_factory=list)
    #: How samples were shaded (Phong, or the machine's reflectance maps); None: unlit.
    shading: str | None = None
    #: Energy per frame and silicon area (:mod:`hwsim.energy`): ``{"technology", "energy",
    #: "area"}`` for cycle and transaction renders; None where no action was counted.
    silicon: dict[str, Any] | None = None
    #: A frame split across workers (:mod:`hwsim.frame_split`): workers, each band's rays,
    #: samples, seconds and peak memory; None: one process.
    split: dict[str, Any] | None = None


def builtin_archs() -> dict[str, ArchConfig]:
    """The built-in machines: every registered family's architecture files
    (``models/machines/<family>/*.toml``), by name, in file-name order."""
    from models.machines import families

    files = [path for family in families() for path in family.arch_files()]
    out = {}
    for path in sorted(files, key=lambda p: p.name):
        cfg = load_arch_file(path)
        out[cfg.name] = cfg
    return out


def resolve_arch(name_or_path: str) -> ArchConfig:
    """An architecture by built-in name or from a user's TOML file."""
    if name_or_path.endswith(".toml") or "/" in name_or_path:
        return load_arch_file(name_or_path)
    archs = builtin_archs()
    if name_or_path not in archs:
        raise InputError(
            f"unknown architecture {name_or_path!r}",
            key="--arch",
            allowed=", ".join(archs) + " or a FILE.toml",
        )
    return archs[name_or_path]


def algorithms(arch: ArchConfig) -> Algorithms:
    """The algorithm choices of ``arch``'s datapath (gradient source, shading method)."""
    from models.datapath import Datapath

    dp = Datapath.from_arch(arch, 0)
    return Algorithms(dp.gradient.source, dp.shade.method, dp.shade.map_size)


def check_scene_fits(scene: Scene, arch: ArchConfig, *, extend: bool = False) -> list:
    """Refuse what the machine cannot render, as the machine did; return the what-if
    extensions ``extend`` lets through (:func:`hwsim.machine_features.require_machine`)."""
    return require_machine(scene, arch, algorithms(arch), extend=extend)


def check_volume_fits(volume: Volume, arch: ArchConfig) -> None:
    """Refuse a volume larger than the machine renders in one pass (every rung alike)."""
    if any(n > m for n, m in zip(volume.shape, arch.max_volume, strict=True)):
        shape = " x ".join(map(str, volume.shape))
        largest = " x ".join(map(str, arch.max_volume))
        raise InputError(
            f"{arch.name} renders volumes up to {largest} (z, y, x) in one pass, not {shape}",
            source=arch.source,
            key="limits.max_volume",
            allowed=f"<= {largest}",
        )


def value_path_volume(scene: Scene, volume: Volume, machine: ArchConfig | None) -> Volume:
    """The volume every rung's value path reads: ``volume``, or the field that
    ``[classification] value_field`` names (VLI's gradient source) as a volume of its own
    that keeps the whole voxels for the other fields (:meth:`Volume.field`).

    Raises
    ------
    InputError
        32-bit voxels on a machine without them, or without a value field (they are
        containers of fields); a value field of data that is not unsigned integers or
        beyond the stored bits.
    """
    spec = scene.classification
    name = spec.value_field if spec is not None else None
    if name is not None:
        f = spec.field(name)  # type: ignore[union-attr]
        if volume.data.dtype.kind != "u" or f.lsb + f.bits > volume.bits:  # type: ignore[union-attr]
            raise InputError(
                f"value field {name!r} (bits {f.lsb}..{f.lsb + f.bits - 1}) is not a bit "  # type: ignore[union-attr]
                f"range of the {volume.data.dtype} voxels of {volume.bits} bits",
                source=scene.source,
                key="classification.value_field",
                allowed="a field of unsigned integer voxels",
            )
        volume = volume.field(f.lsb, f.bits, name)  # type: ignore[union-attr]
    container = int(volume.meta.get("container_bits", 0)) or volume.bits
    if machine is not None and container > 16:
        if 32 not in machine.voxel_bits:
            raise InputError(
                f"{machine.name} stores voxels of at most {max(machine.value_bits)} bits, "
                f"not {container}",
                source=machine.source,
                key="limits.voxel_bits",
                allowed=", ".join(map(str, machine.voxel_bits)),
            )
        if name is None:
            raise InputError(
                f"{container}-bit voxels are containers of fields: name the one the value "
                "path reads",
                source=scene.source,
                key="classification.value_field",
                allowed="a declared [[classification.fields]] name",
            )
    return volume


def _supervolume_extension(volume: Volume, arch: ArchConfig) -> Extension:
    """A volume over ``max_volume`` rendered in bricks on a machine without supervolumes."""
    shape = " x ".join(map(str, volume.shape))
    source = arch.feature_sources.get("supervolumes", "[?] not declared in the arch file")
    return Extension("supervolumes", "limits.max_volume", f"a {shape} supervolume", "none", source)


def times_back_to_back(arch: ArchConfig) -> bool:
    """Whether ``arch``'s cycle model times back-to-back frames (``steady_state``)."""
    from models.machines import machine_for

    try:
        return machine_for(arch).steady_state
    except NotAvailableError:
        return False


def machine_rungs(arch: ArchConfig) -> list[str]:
    """The rungs that model ``arch`` (golden and functional model every machine)."""
    from models.machines import machine_for

    try:
        machine = machine_for(arch)
    except NotAvailableError:
        return ["golden", "functional"]
    modelled = {"transaction": machine.transaction, "cycle": machine.cycle}
    rungs = ["golden", "functional"] + [r for r, model in modelled.items() if model is not None]
    return rungs + (["rtl"] if machine.rtl_top else [])


def elaboration(scene: Scene, transfer: TransferFunction) -> tuple[list[str], list[str]]:
    """Which stages a scene needs (design section 3, "model only what a scene requires"):
    :func:`models.datapath.units_needed`, plus the units only some machines have
    (multi-LUT combiners, the depth test), listed when a scene uses them and never as
    elided (a machine without them cannot elide them)."""
    from models.datapath import units_needed

    needs = units_needed(scene, transfer.modulates)
    used = [u for u, needed in needs.items() if needed]
    if scene.classification is not None:
        used.insert(used.index("classify") + 1, "combine")
    if scene.geometry is not None:
        used.append("depth")
    return used, [u for u, needed in needs.items() if not needed]


#: Bytes the renderers hold per image pixel (ray state, colour and opacity, positions;
#: the golden rung measured about 450) and per voxel (the derived float copies and
#: gradients the renderers cache per volume).
BYTES_PER_PIXEL = 512
BYTES_PER_VOXEL = 48


def check_work(scene: Scene, volume: Volume, *, whole_volume: bool = True) -> None:
    """Refuse, before any work, a frame whose samples or memory exceed the budgets.

    Samples are bounded by ``pixels x (volume diagonal / sample step + 1)``; memory by
    :data:`BYTES_PER_PIXEL` per pixel plus :data:`BYTES_PER_VOXEL` per voxel.
    """
    pixels = scene.view.width * scene.view.height
    step = scene.render.step * min(volume.spacing)
    per_ray = int(np.ceil(float(np.linalg.norm(volume.extent)) / step)) + 1
    samples = pixels * per_ray
    if samples > sample_budget():
        raise InputError(
            f"the frame would plan up to {samples:.3g} samples ({pixels} rays x {per_ray} "
            f"steps of {scene.render.step:g} voxel) over the budget of {sample_budget():.3g}",
            key="render.sample_spacing",
            allowed=f"a coarser sample spacing, a smaller image, or {SAMPLE_ENV_VAR}",
        )
    voxels = int(np.prod(volume.shape)) if whole_volume else 0  # read in parts: per worker
    nbytes = BYTES_PER_PIXEL * pixels + BYTES_PER_VOXEL * voxels
    require_fits(nbytes, what=f"a {scene.view.width}x{scene.view.height} frame", key="view")


def render(
    scene: Scene,
    *,
    fidelity: str = "golden",
    arch: str | ArchConfig | None = None,
    sampling: str = "ray",
    volume: Volume | None = None,
    progress: Progress | None = None,
    trace: str | Path | None = None,
    elaborate_all: bool = False,
    steady_state: bool = False,
    simulator: str | None = None,
    extend: bool = False,
    timing_only: bool = False,
    technology: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    bands: int | None = None,
) -> RenderRun:
    """Render ``scene`` at ``fidelity``.

    Parameters
    ----------
    scene : Scene
        The validated scene.
    fidelity : str
        One of :data:`FIDELITIES`.
    arch : str or ArchConfig, optional
        Architecture name, file or config (a sweep's overrides).  At the golden rung
        it selects the machine's sample positions (so golden vs. a timed rung differs
        only numerically).
    sampling : str
        Sample positions of the golden rung without ``arch``: the ideal ``ray`` caster
        or an architecture's (``shear-warp``, ``shear-image``, ``slice-parallel``).
    volume : Volume, optional
        An already loaded volume (skips loading ``scene.volume``).
    progress : callable, optional
        ``progress(done, total)`` called as the render advances.
    trace : path, optional
        ``cycle`` and ``rtl`` rungs: write a VCD waveform of the modelled hardware there.
    elaborate_all : bool
        ``cycle`` rung only: simulate every unit, even those the scene does not use (the
        reference that elision is measured against; same image and cycles).
    steady_state : bool
        ``cycle`` and ``transaction`` rungs, VolumePro family: also time the next frame
        back to back (``frame.period_cycles`` in the counters: the continuous frame rate).
    simulator : str, optional
        ``rtl`` rung only: ``verilator`` (the default) or ``icarus``.
    extend : bool
        Render a scene outside the machine's declared features as a what-if (listed in
        ``extensions``) instead of refusing it (:mod:`hwsim.machine_features`).
    timing_only : bool
        ``transaction`` rung only: time the frame without its image (``image`` is None;
        :func:`models.transaction.timing_only`).
    technology : str, optional
        ``cycle`` and ``transaction`` rungs: price the frame's actions and the machine's
        area in this technology (a built-in name or a TOML file; default: the machine's
        ``[silicon] technology``), :mod:`hwsim.energy`.
    workers, scheduler, bands : optional
        ``cycle`` rung: split the frame across a local Dask cluster of ``workers``
        processes, or the cluster at ``scheduler``, in ``bands`` bands of rays (default:
        one per worker), reading the volume in parts (:mod:`hwsim.frame_split`); the same
        image, cycles and counters as one process.  What the split did is ``split``.
    """
    if fidelity not in FIDELITIES:
        raise InputError(
            f"unknown fidelity {fidelity!r}", key="--fidelity", allowed=", ".join(FIDELITIES)
        )
    if steady_state and fidelity not in ("cycle", "transaction"):
        raise InputError(
            "only the cycle and transaction rungs time back-to-back frames",
            key="steady_state",
            allowed="cycle, transaction",
        )
    if timing_only and fidelity != "transaction":
        raise InputError(
            "only the transaction rung times a frame without its image",
            key="--timing-only",
            allowed="--fidelity transaction",
        )
    if elaborate_all and fidelity != "cycle":
        raise InputError("only the cycle rung elaborates units", key="elaborate_all")
    if trace is not None and fidelity not in ("cycle", "rtl"):
        raise InputError(
            "a waveform needs --fidelity cycle or rtl", key="--trace", allowed="cycle, rtl"
        )
    if simulator is not None and fidelity != "rtl":
        raise InputError(
            "an HDL simulator runs the rtl rung only", key="--simulator", allowed="rtl"
        )
    split = workers is not None or scheduler is not None
    if split:
        _check_split(fidelity, volume, workers, scheduler, bands, elaborate_all, steady_state)
    if arch is None and fidelity != "golden":
        arch = DEFAULT_ARCH
    if isinstance(arch, ArchConfig):
        machine: ArchConfig | None = arch
    else:
        machine = resolve_arch(arch) if arch is not None else None
    if technology is not None:  # a bad technology is refused before the frame is computed
        from hwsim.energy import load_technology

        load_technology(technology)
    extensions = []
    chosen = IDEAL  # the ideal renderer's shading (its gradients: the scene's, or voxel)
    if machine is not None:
        extensions = check_scene_fits(scene, machine, extend=extend)
        chosen = algorithms(machine)
        if scene.render.gradient is None:  # golden follows the machine's algorithm too
            gradient = chosen.gradient
            scene = scene.replace(render=dataclasses.replace(scene.render, gradient=gradient))
        if sampling not in ("ray", machine.order):
            raise InputError(
                f"{machine.name} samples in {machine.order} order",
                key="--sampling",
                allowed=f"{machine.order} (or omit it)",
            )
        sampling = machine.order
    if sampling not in SAMPLINGS:
        raise InputError(
            f"unknown sampling {sampling!r}", key="--sampling", allowed=", ".join(SAMPLINGS)
        )
    from hwsim.golden import render_golden  # deferred: keeps `hwsim scenes` fast

    if split:
        from hwsim.volumes.parts import volume_parts

        volume = volume_parts(scene.volume, scene.base_dir).volume()
    elif volume is None:
        volume = load_volume(scene.volume, scene.base_dir)
    volume = value_path_volume(scene, volume, machine)
    check_work(scene, volume, whole_volume=not split)
    bricked = False
    if machine is not None and oversize(volume, machine):
        if not (machine.supervolumes or extend):
            check_volume_fits(volume, machine)  # refuses, naming limits.max_volume
        if not machine.supervolumes:
            extensions.append(_supervolume_extension(volume, machine))
        if fidelity != "golden":  # golden renders the whole volume at the machine's positions
            refuse_supervolume(
                scene,
                machine,
                fidelity,
                trace=trace,
                steady_state=steady_state,
                elaborate_all=elaborate_all,
            )
            bricked = True
    transfer = resolve_transfer(scene.transfer, volume, scene.base_dir)
    used, elided = elaboration(scene, transfer)
    cycles = clock = None
    silicon = split_info = None
    derived: dict[str, Any] = {}
    if fidelity == "golden" and machine is not None:  # the machine's refusals hold here too
        from models.frame import frame_of

        check_family(frame_of(scene, volume, transfer, machine))
    start = time.perf_counter()
    if fidelity == "golden":
        maps = chosen.map_size if chosen.shading == "reflectance-map" else None
        result = render_golden(
            scene, volume, transfer, sampling=sampling, progress=progress, reflectance_map=maps
        )
        counters = {"golden.samples": int(result.samples), "golden.rays": int(result.rays)}
    else:
        from models.frame import frame_of

        if timing_only and bricked:
            raise InputError(
                "a supervolume's host blend needs its bricks' images",
                key="--timing-only",
                allowed=f"a volume of at most {' x '.join(map(str, machine.max_volume))}",  # type: ignore[union-attr]
            )
        if timing_only:
            from models.transaction import timing_only as time_frame

            frame = frame_of(scene, volume, transfer, machine)
            check_family(frame)
            result = time_frame(frame, steady_state=steady_state)
        elif split:
            from hwsim.frame_split import split_frame

            if bricked:
                raise InputError(
                    "a supervolume's bricks are frames of their own",
                    key="--workers",
                    allowed=f"a volume of at most {' x '.join(map(str, machine.max_volume))}",  # type: ignore[union-attr]
                )
            frame = frame_of(scene, volume, transfer, machine)
            check_family(frame)
            result, split_info = split_frame(
                frame,
                workers=workers,
                scheduler=scheduler,
                bands=bands,
                progress=progress,
                trace=trace is not None,
            )
        elif bricked:

            def one_brick(frame):
                return _render_machine(frame, fidelity, None, None, False, False, None)

            result = render_bricks(scene, volume, transfer, machine, one_brick, frame_of, progress)
        else:
            frame = frame_of(scene, volume, transfer, machine)
            result = _render_machine(
                frame, fidelity, progress, trace, elaborate_all, steady_state, simulator
            )
        cycles, clock, counters = result.cycles, machine.clock_hz, result.counters
        if fidelity in ("cycle", "transaction") or bricked:
            derived = result.derived
        if fidelity in ("cycle", "rtl"):
            used, elided = result.elaborated_units, result.elided_units
        if fidelity in ("cycle", "transaction") and not bricked:
            from hwsim.energy import estimate_frame

            silicon = estimate_frame(frame, counters, used, cycles, technology)
    wall = time.perf_counter() - start
    return RenderRun(
        scene=scene,
        volume=volume,
        transfer=transfer,
        fidelity=fidelity,
        arch=machine.name if machine else None,
        sampling=sampling,
        image=result.image,
        samples=int(result.samples),
        rays=int(result.rays),
        wall_seconds=wall,
        cycles=cycles,
        clock_hz=clock,
        elaborated_units=used,
        elided_units=elided,
        counters=counters,
        derived=derived,
        extensions=[e.describe() for e in extensions],
        shading=chosen.describe_shading() if scene.lit else None,
        silicon=silicon,
        split=split_info,
    )


def _check_split(fidelity, volume, workers, scheduler, bands, elaborate_all, steady_state) -> None:
    """Refuse, before any work, what a frame split across workers cannot be."""
    if fidelity != "cycle":
        raise InputError(
            f"the {fidelity} rung renders a frame in one process",
            key="--workers",
            allowed="--fidelity cycle",
        )
    if workers is not None and scheduler is not None:
        raise InputError(
            "give a worker count or a scheduler, not both", key="--workers", allowed="one of them"
        )
    if workers is not None and not (isinstance(workers, int) and 1 <= workers <= MAX_WORKERS):
        raise InputError(
            f"{workers!r} is out of range", key="--workers", allowed=f"1 .. {MAX_WORKERS}"
        )
    if bands is not None and not (isinstance(bands, int) and 1 <= bands <= MAX_WORKERS):
        raise InputError(f"{bands!r} is out of range", key="--bands", allowed=f"1 .. {MAX_WORKERS}")
    if volume is not None:
        raise InputError(
            "a frame split across workers reads its volume in parts, not a loaded volume",
            key="volume",
            allowed="the scene's volume file or phantom",
        )
    for flag, given in (("--elaborate-all", elaborate_all), ("--steady-state", steady_state)):
        if given:
            raise InputError("renders in one process", key=flag, allowed="no --workers")


def check_family(frame) -> None:
    """The refusals of the family modelling ``frame``'s machine (``Machine.check_frame``):
    asked before every rung, so a scene its models cannot render is refused at all."""
    from models.machines import machine_for

    try:
        family = machine_for(frame.arch)
    except NotAvailableError:
        return  # no family models this order: the rungs say so themselves
    if family.check_frame is not None:
        family.check_frame(frame)


def _render_machine(frame, fidelity, progress, trace, elaborate_all, steady_state, simulator):
    """``frame`` at ``fidelity``, one of the machine rungs (imported on use: each pulls in
    its models), after the family's own refusals (the same for every rung)."""
    check_family(frame)
    if fidelity == "cycle":
        from models.cycle import render_cycle

        return render_cycle(
            frame,
            trace=trace,
            progress=progress,
            elaborate_all=elaborate_all,
            steady_state=steady_state,
        )
    if fidelity == "transaction":
        from models.transaction import render_transaction

        return render_transaction(frame, progress=progress, steady_state=steady_state)
    if fidelity == "rtl":
        from rtl.rung import render_rtl

        return render_rtl(frame, simulator=simulator or "verilator", trace=trace)
    from models.functional import render_functional

    return render_functional(frame, progress=progress)
