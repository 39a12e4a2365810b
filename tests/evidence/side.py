"""One side of a comparison, run in a process of its own from a given source tree.

    python side.py ROOT JOB OUT SPEC_JSON

``ROOT`` holds ``hwsim/``, ``models/`` and ``rtl/`` (the repository, or a mutated copy of
it, first on ``PYTHONPATH``); the script first checks that every package it imports
comes from ``ROOT`` (the venv's editable install must not win), then runs ``JOB`` with
the parameters in ``SPEC_JSON`` and writes ``OUT/result.json`` (cycles, samples,
counters, the packages' files) and, where the job has one, ``OUT/image.npy``.

Every job calls the entry points the existing tests call for the same comparison, so a
result here is what those tests would compare:

* ``cube4``: a Cube-4 frame of the head phantom at the ``cycle`` or ``rtl`` rung through
  :func:`hwsim.run.fidelity.render` (``tests/cosim/test_top_rung.py``), optionally with a
  shallower pixel FIFO (``tests/cosim/test_top_cosim.py``);
* ``golden`` / ``functional``: the frame at a machine's sample positions, golden with
  ``leap=False`` (``tests/models/test_functional.py``, ``pair``);
* ``vp_cycle`` / ``vp_transaction``: a VolumePro-family frame's cycles and counters at
  the cycle rung and the transaction rung's event model, optionally at a chunk size
  ``groups`` (``tests/models/test_transaction_volumepro.py``, ``tests/memory/memory_timing.py``);
* ``split``: a Cube-4 cycle frame cut into bands of rays, each band run as a worker runs
  it, combined (``tests/models/test_split_frame.py``); ``bands = 0`` is the one-process
  frame.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np


def _check_root(root: Path) -> dict[str, str]:
    """The packages' files, each required to lie inside ``root``."""
    import hwsim
    import models
    import rtl

    files = {}
    for module in (hwsim, models, rtl):
        path = Path(module.__file__).resolve()
        if not path.is_relative_to(root):
            raise SystemExit(f"{module.__name__} imported from {path}, not from {root}")
        files[module.__name__] = str(path)
    return files


def _head_scene(spec: dict):
    from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec

    image = spec.get("image", 12)
    return Scene(
        volume=VolumeSpec(phantom="head"),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(
            azimuth=spec.get("az", 30),
            elevation=spec.get("el", 20),
            width=image,
            height=image,
            zoom=spec.get("zoom", 1.2),
        ),
        render=RenderSpec(mode=spec.get("mode", "composite"), lighting=spec.get("lit", True)),
    )


def _arch(spec: dict):
    from hwsim.run.fidelity import resolve_arch

    arch = resolve_arch(spec.get("arch", "cube4"))
    if "memory" in spec:
        arch = dataclasses.replace(arch, memory={**arch.memory, **spec["memory"]})
    if "pixel_fifo" in spec:
        arch = dataclasses.replace(
            arch, buffers={**arch.buffers, "pixel_fifo_entries": spec["pixel_fifo"]}
        )
    return arch


def job_cube4(spec: dict) -> dict:
    """A Cube-4 frame at ``spec["fidelity"]`` (``cycle`` or ``rtl`` on ``simulator``)."""
    from hwsim.run.fidelity import render
    from hwsim.volumes import make_phantom

    fidelity = spec["fidelity"]
    run = render(
        _head_scene(spec),
        fidelity=fidelity,
        arch=_arch(spec),
        volume=make_phantom("head", size=spec.get("size", 8)),
        simulator=spec.get("simulator") if fidelity == "rtl" else None,
    )
    return {
        "image": run.image,
        "cycles": run.cycles,
        "samples": run.samples,
        "stall_cycles": run.counters.get("pixel_bus.stall_cycles"),
    }


def _machine_frame(spec: dict):
    from hwsim.golden import make_plan
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import make_phantom
    from models.frame import frame_of

    scene = _head_scene(spec)
    volume = make_phantom("head", size=spec["size"])
    machine = _arch(spec)
    transfer = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    return scene, volume, transfer, machine, frame_of(scene, volume, transfer, machine, plan)


def job_golden(spec: dict) -> dict:
    """Golden at the machine's sample positions and with its algorithms (its gradient
    source, its reflectance maps), every position planned (no leaping): as
    ``tests/models/numeric_bound.py`` ``golden_at_machine`` renders it."""
    from hwsim.golden import render_golden
    from hwsim.run.fidelity import algorithms

    scene, volume, transfer, machine, _ = _machine_frame(spec)
    chosen = algorithms(machine)
    scene = scene.replace(render=dataclasses.replace(scene.render, gradient=chosen.gradient))
    maps = chosen.map_size if chosen.shading == "reflectance-map" else None
    result = render_golden(
        scene, volume, transfer, sampling=machine.order, leap=False, reflectance_map=maps
    )
    return {"image": result.image, "samples": result.samples}


def job_functional(spec: dict) -> dict:
    from models.functional import render_functional

    *_, frame = _machine_frame(spec)
    result = render_functional(frame)
    return {"image": result.image, "samples": result.samples}


def job_vp_cycle(spec: dict) -> dict:
    from models.cycle import render_cycle

    *_, frame = _machine_frame(spec)
    result = render_cycle(frame)
    return {"cycles": result.cycles, "samples": result.samples, "counters": _plain(result)}


def job_vp_transaction(spec: dict) -> dict:
    from models.transaction import transaction_timing

    *_, frame = _machine_frame(spec)
    # ``groups``: the event model's chunk size (tests/memory/memory_timing.py compares the
    # memory stall at its finest, one mini-block beam per chunk).
    options = {"groups": spec["groups"]} if "groups" in spec else {}
    timing = transaction_timing(frame, **options)
    return {"cycles": timing.cycles, "counters": _plain(timing)}


def _plain(run) -> dict:
    """A run's numeric and text counters, JSON-ready."""
    return {
        k: v if isinstance(v, str) else int(v)
        for k, v in run.counters.items()
        if isinstance(v, (str, int, float, np.integer, np.floating))
    }


def job_split(spec: dict) -> dict:
    """The frame in ``spec["bands"]`` bands as workers run them (no Dask), or in one
    process (``bands = 0``)."""
    from hwsim.spec.scene import VolumeSpec
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import load_volume
    from hwsim.volumes.parts import volume_parts
    from models.cycle import render_cycle
    from models.frame import frame_of
    from models.machines.cube4.bands import BandSplit, sweep_band

    scene = _head_scene(spec)
    scene = dataclasses.replace(
        scene, volume=VolumeSpec(phantom="head", params=(("size", spec["size"]),))
    )
    if spec["bands"] == 0:  # the one-process frame: the whole volume, loaded
        volume = load_volume(scene.volume)
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), _arch(spec))
        result = render_cycle(frame)
    else:  # the volume read a box at a time, as a worker reads it
        parts = volume_parts(scene.volume)
        volume = parts.volume()
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), _arch(spec))
        split = BandSplit(frame)
        groups = split.bands(spec["bands"])
        sweeps = [sweep_band(frame, parts, rays, b)[0] for b, rays in enumerate(groups)]
        result = split.combine(sweeps)
    return {"image": result.image, "cycles": result.cycles, "samples": result.samples}


JOBS = {
    "cube4": job_cube4,
    "golden": job_golden,
    "functional": job_functional,
    "vp_cycle": job_vp_cycle,
    "vp_transaction": job_vp_transaction,
    "split": job_split,
}


def main(argv: list[str]) -> None:
    root, job, out, spec = Path(argv[0]).resolve(), argv[1], Path(argv[2]), json.loads(argv[3])
    files = _check_root(root)
    result = JOBS[job](spec)
    out.mkdir(parents=True, exist_ok=True)
    image = result.pop("image", None)
    if image is not None:
        np.save(out / "image.npy", image)
    result["files"] = files
    (out / "result.json").write_text(json.dumps(result, indent=1, default=int) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
