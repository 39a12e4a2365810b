"""The fidelity ladder: one entry point, five rungs (design section 3).

``render(scene, fidelity=...)`` loads the scene's volume and transfer function, runs the
requested rung and returns a :class:`RenderRun` holding the image and the raw numbers
``stats.json`` is written from.  A rung that does not model the machine (no family in
the registry, ``models.machines``, has it at that rung) raises
:class:`~hwsim.core.errors.NotAvailableError` (exit status 2 at the CLI).  The options are one
:class:`~hwsim.run.render_request.RenderRequest` (or its fields as keywords), refused when it
is made; :data:`EXECUTIONS` chooses how the frame runs (golden, one process, timing only,
split across workers, bricks of a supervolume).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.budget import SAMPLE_ENV_VAR, require_fits, sample_budget
from hwsim.core.errors import InputError, NotAvailableError
from hwsim.run.render_request import (  # noqa: F401  (re-exported: callers import them from here)
    DEFAULT_ARCH,
    FIDELITIES,
    MAX_WORKERS,
    SAMPLINGS,
    RenderRequest,
)
from hwsim.run.supervolume import oversize, refuse_supervolume, render_bricks
from hwsim.spec.arch import ArchConfig, load_arch_file
from hwsim.spec.machine_features import IDEAL, Algorithms, Extension, require_machine
from hwsim.spec.preset_choice import resolve_auto
from hwsim.spec.scene import Scene
from hwsim.spec.transfer import TransferFunction, resolve_transfer
from hwsim.volumes import load_volume
from hwsim.volumes.volume import Volume

__all__ = [
    "FIDELITIES",
    "SAMPLINGS",
    "RenderRequest",
    "RenderRun",
    "render",
    "builtin_archs",
    "load_machine",
    "resolve_arch",
]


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
    #: A frame split across workers (:mod:`hwsim.run.frame_split`): workers, each band's rays,
    #: samples, seconds and peak memory; None: one process.
    split: dict[str, Any] | None = None


def builtin_archs() -> dict[str, ArchConfig]:
    """The built-in machines: every registered family's architecture files
    (``models/machines/<family>/*.toml``), by name, in file-name order."""
    from models.machines import families

    files = [path for family in families() for path in family.arch_files()]
    out = {}
    for path in sorted(files, key=lambda p: p.name):
        cfg = load_machine(path)
        out[cfg.name] = cfg
    return out


def load_machine(path: str | Path) -> ArchConfig:
    """An architecture file, validated whole before any work: its generic shape
    (:func:`hwsim.spec.arch.load_arch_file`), then the tables the models own (``[formats]``,
    the family's ``[buffers]`` and rules: :func:`models.machines.check_tables`)."""
    from models.machines import check_tables

    return check_tables(load_arch_file(path))


def resolve_arch(name_or_path: str) -> ArchConfig:
    """An architecture by built-in name or from a user's TOML file."""
    if name_or_path.endswith(".toml") or "/" in name_or_path:
        from hwsim.energy import arch_technology

        config = load_machine(name_or_path)
        arch_technology(config)  # an unknown [silicon] technology: refused at load
        return config
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
    extensions ``extend`` lets through (:func:`hwsim.spec.machine_features.require_machine`)."""
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
    rtl = machine.rtl_top and (machine.rtl_archs is None or machine.rtl_archs(arch))
    return rungs + (["rtl"] if rtl else [])


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


def render(scene: Scene, request: RenderRequest | None = None, **keywords: Any) -> RenderRun:
    """Render ``scene`` as ``request`` asks, or as ``keywords`` do (the fields of
    :class:`~hwsim.run.render_request.RenderRequest`, which says what each means; given both,
    the keywords replace the request's fields): ``render(scene, fidelity="cycle",
    arch="cube4")`` is ``render(scene, RenderRequest(fidelity="cycle", arch="cube4"))``.

    The request is refused before any work if no rung renders it; then the machine, the
    volume and the transfer function are resolved (:func:`_prepare`) and the first of
    :data:`EXECUTIONS` that applies renders the frame.
    """
    request = RenderRequest.of(request, **keywords)
    job = _prepare(scene, request)
    _, execute = choose_execution(job)
    start = time.perf_counter()
    result, facts = execute(job)
    wall = time.perf_counter() - start
    fields: dict[str, Any] = {
        "elaborated_units": job.used,
        "elided_units": job.elided,
        **facts,
    }
    return RenderRun(
        scene=job.scene,
        volume=job.volume,
        transfer=job.transfer,
        fidelity=request.fidelity,
        arch=job.machine.name if job.machine else None,
        sampling=job.sampling,
        image=result.image,
        samples=int(result.samples),
        rays=int(result.rays),
        wall_seconds=wall,
        extensions=[e.describe() for e in job.extensions],
        shading=job.chosen.describe_shading() if job.scene.lit else None,
        **fields,
    )


@dataclass(frozen=True, kw_only=True)
class RenderJob:
    """A request resolved against its scene: the machine, the loaded volume and transfer
    function, the sample order, and whether the volume is rendered in bricks."""

    scene: Scene  # with the machine's gradient source where the scene names none
    request: RenderRequest
    machine: ArchConfig | None
    chosen: Algorithms  # the machine's shading (or the ideal renderer's)
    extensions: list[Extension]
    sampling: str
    volume: Volume
    transfer: TransferFunction
    used: list[str]
    elided: list[str]
    bricked: bool

    def frame(self):
        """The :class:`models.frame.Frame` of the whole volume on the machine."""
        from models.frame import frame_of

        return frame_of(self.scene, self.volume, self.transfer, self.machine)


def _prepare(scene: Scene, request: RenderRequest) -> RenderJob:
    """Resolve ``request`` for ``scene``, refusing (before any rendering) what the
    machine, the technology, the sample order or the volume rule out."""
    wanted = request.machine
    if isinstance(wanted, ArchConfig):
        machine: ArchConfig | None = wanted
    else:
        machine = resolve_arch(wanted) if wanted is not None else None
    if request.technology is not None or machine is not None:  # refused before the frame
        from hwsim.energy import arch_technology

        arch_technology(machine, request.technology)
    extensions = []
    chosen = IDEAL  # the ideal renderer's shading (its gradients: the scene's, or voxel)
    if machine is not None:
        extensions = check_scene_fits(scene, machine, extend=request.extend)
        chosen = algorithms(machine)
        if scene.render.gradient is None:  # golden follows the machine's algorithm too
            gradient = chosen.gradient
            scene = scene.replace(render=dataclasses.replace(scene.render, gradient=gradient))
    sampling = request.refuse_order(machine)
    volume = _load_volume(scene, request, machine)
    if scene.classification is None:  # `auto` chosen once: every rung, the stats see it
        scene = scene.replace(transfer=resolve_auto(scene.transfer, volume))
    bricked = _bricks_of(scene, request, machine, volume, extensions)
    transfer = resolve_transfer(scene.transfer, volume, scene.base_dir)
    used, elided = elaboration(scene, transfer)
    return RenderJob(
        scene=scene,
        request=request,
        machine=machine,
        chosen=chosen,
        extensions=extensions,
        sampling=sampling,
        volume=volume,
        transfer=transfer,
        used=used,
        elided=elided,
        bricked=bricked,
    )


def _load_volume(scene: Scene, request: RenderRequest, machine: ArchConfig | None) -> Volume:
    """The volume the value path reads, refused if the frame is over the budgets."""
    if request.split:
        from hwsim.volumes.parts import volume_parts

        volume = volume_parts(scene.volume, scene.base_dir).volume()
    elif request.volume is None:
        volume = load_volume(scene.volume, scene.base_dir)
    else:
        volume = request.volume
    volume = value_path_volume(scene, volume, machine)
    check_work(scene, volume, whole_volume=not request.split)
    return volume


def _bricks_of(
    scene: Scene,
    request: RenderRequest,
    machine: ArchConfig | None,
    volume: Volume,
    extensions: list[Extension],
) -> bool:
    """Whether ``volume`` is rendered in bricks (a supervolume over the machine's
    ``max_volume``); refuses what the bricks cannot model, and lists the what-if."""
    if machine is None or not oversize(volume, machine):
        return False
    if not (machine.supervolumes or request.extend):
        check_volume_fits(volume, machine)  # refuses, naming limits.max_volume
    if not machine.supervolumes:
        extensions.append(_supervolume_extension(volume, machine))
    if request.fidelity == "golden":  # the whole volume at the machine's positions
        return False
    refuse_supervolume(
        scene,
        machine,
        request.fidelity,
        trace=request.trace,
        steady_state=request.steady_state,
        elaborate_all=request.elaborate_all,
    )
    request.refuse_bricks(machine)
    return True


#: What an execution returns: the rung's result (image, samples, rays) and the
#: :class:`RenderRun` fields it sets beyond those every render has.
Executed = tuple[Any, dict[str, Any]]


def _golden(job: RenderJob) -> Executed:
    """The golden rung, at the machine's sample positions and shading if one is named
    (after the machine's own refusals)."""
    from hwsim.golden import render_golden  # deferred: keeps `hwsim scenes` fast

    if job.machine is not None:
        check_family(job.frame())
    chosen = job.chosen
    maps = chosen.map_size if chosen.shading == "reflectance-map" else None
    result = render_golden(
        job.scene,
        job.volume,
        job.transfer,
        sampling=job.sampling,
        progress=job.request.progress,
        reflectance_map=maps,
    )
    counters = {"golden.samples": int(result.samples), "golden.rays": int(result.rays)}
    return result, {"counters": counters}


def _timing_only(job: RenderJob) -> Executed:
    """The transaction rung's timing without the image."""
    from models.transaction import timing_only as time_frame

    frame = job.frame()
    check_family(frame)
    result = time_frame(frame, steady_state=job.request.steady_state, progress=job.request.progress)
    return result, _machine_facts(job, result, frame)


def _split(job: RenderJob) -> Executed:
    """The cycle rung, one band of rays per task across workers."""
    from hwsim.run.frame_split import split_frame

    request = job.request
    frame = job.frame()
    check_family(frame)
    result, split = split_frame(
        frame,
        workers=request.workers,
        scheduler=request.scheduler,
        bands=request.bands,
        progress=request.progress,
        trace=request.trace is not None,
    )
    return result, {**_machine_facts(job, result, frame), "split": split}


def _bricks(job: RenderJob) -> Executed:
    """A supervolume: each brick a frame of the rung, blended as the host did."""
    from models.frame import frame_of

    plain = RenderRequest(fidelity=job.request.fidelity)  # a brick: no trace, no progress

    def one_brick(frame):
        return _render_machine(frame, plain)

    result = render_bricks(
        job.scene, job.volume, job.transfer, job.machine, one_brick, frame_of, job.request.progress
    )
    return result, _machine_facts(job, result, None)


def _one_process(job: RenderJob) -> Executed:
    """A machine rung (functional, transaction, cycle, rtl) in this process."""
    frame = job.frame()
    result = _render_machine(frame, job.request)
    return result, _machine_facts(job, result, frame)


def _machine_facts(job: RenderJob, result, frame) -> dict[str, Any]:
    """What a machine rung's ``result`` sets: cycles, clock and counters; derived figures
    (timed rungs, bricks); the units simulated (cycle, rtl); energy and area (timed
    rungs, one frame of the whole volume)."""
    fidelity = job.request.fidelity
    facts: dict[str, Any] = {
        "cycles": result.cycles,
        "clock_hz": job.machine.clock_hz,  # type: ignore[union-attr]
        "counters": result.counters,
    }
    if fidelity in ("cycle", "transaction") or job.bricked:
        facts["derived"] = result.derived
    used = job.used
    if fidelity in ("cycle", "rtl"):
        used = facts["elaborated_units"] = result.elaborated_units
        facts["elided_units"] = result.elided_units
    if fidelity in ("cycle", "transaction") and not job.bricked:
        from hwsim.energy import estimate_frame

        technology = job.request.technology
        facts["silicon"] = estimate_frame(frame, result.counters, used, result.cycles, technology)
    return facts


#: How a frame is executed: the first entry whose test holds for the job renders it.  A
#: new way of executing a frame is a function and an entry here, not a branch in render.
EXECUTIONS: tuple[tuple[str, Callable[[RenderJob], bool], Callable[[RenderJob], Executed]], ...] = (
    ("golden", lambda job: job.request.fidelity == "golden", _golden),
    ("timing-only", lambda job: job.request.timing_only, _timing_only),
    ("split", lambda job: job.request.split, _split),
    ("bricks", lambda job: job.bricked, _bricks),
    ("one process", lambda job: True, _one_process),
)


def choose_execution(job: RenderJob) -> tuple[str, Callable[[RenderJob], Executed]]:
    """The name and function of the first of :data:`EXECUTIONS` that applies to ``job``."""
    return next((name, run) for name, applies, run in EXECUTIONS if applies(job))


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


def _require_rtl_top(arch: ArchConfig) -> None:
    """Refuse the rtl rung for an arch whose family declares no RTL top for it
    (``Machine.rtl_top``, ``Machine.rtl_archs``): a top is another machine's hardware, so a
    Cube-1 (slice-parallel too) must not be rendered by the Cube-4 top."""
    if "rtl" in machine_rungs(arch):
        return
    tops = [name for name, cfg in builtin_archs().items() if "rtl" in machine_rungs(cfg)]
    raise NotAvailableError(
        f"{arch.name} has no RTL top (the rtl rung builds only its own machine's hardware)",
        key="--arch",
        allowed=", ".join(tops) + " or a FILE.toml of their families",
    )


def _render_machine(frame, request: RenderRequest):
    """``frame`` at ``request.fidelity``, one of the machine rungs (imported on use: each
    pulls in its models), after the family's own refusals (the same for every rung)."""
    check_family(frame)
    fidelity, progress, trace = request.fidelity, request.progress, request.trace
    if fidelity == "cycle":
        from models.cycle import render_cycle

        return render_cycle(
            frame,
            trace=trace,
            progress=progress,
            elaborate_all=request.elaborate_all,
            steady_state=request.steady_state,
        )
    if fidelity == "transaction":
        from models.transaction import render_transaction

        return render_transaction(frame, progress=progress, steady_state=request.steady_state)
    if fidelity == "rtl":
        from rtl.rung import render_rtl

        _require_rtl_top(frame.arch)
        simulator = request.simulator or "verilator"
        return render_rtl(frame, simulator=simulator, trace=trace, progress=progress)
    from models.functional import render_functional

    return render_functional(frame, progress=progress)
