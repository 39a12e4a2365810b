"""``hwsim render`` (one frame, a turntable, a frame split across workers) and ``hwsim
convert``: what the command line does with their arguments and what it prints.

``hwsim.cli.commands`` builds the parser and dispatches here.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hwsim.cli.progress import progress_bar
from hwsim.core.errors import InputError
from hwsim.core.threads import using as using_threads
from hwsim.spec.overrides import apply_overrides

if TYPE_CHECKING:
    from hwsim.spec.scene import Scene

__all__ = ["DEFAULT_RENDER_OUT", "cmd_render", "cmd_convert"]

#: Where ``hwsim render`` writes without ``--out`` (the summary says when it replaced a render).
DEFAULT_RENDER_OUT = "out/render"


def cmd_render(args: argparse.Namespace) -> int:
    with using_threads(args.threads):  # read by every frame kernel
        return _render_command(args)


def _render_command(args: argparse.Namespace) -> int:
    """Parse, load, call :func:`hwsim.api.render`, save, summarise."""
    from hwsim.api import naming_flags, render
    from hwsim.spec.scene import load_scene

    scene = apply_overrides(load_scene(args.scene), args)
    out_dir = args.out if args.out is not None else DEFAULT_RENDER_OUT
    replacing = args.out is None and (Path(out_dir) / "stats.json").is_file()
    options = _render_options(args)
    turntable = args.frames != 1 or args.turn is not None
    if turntable:
        _check_turntable(args, options)
    _plan_render(scene, args, out_dir, turntable)  # every output, before the work starts
    if turntable:
        return _turntable(scene, args, out_dir, options)
    fidelity, arch = options.pop("fidelity"), options.pop("arch")
    with naming_flags(), progress_bar(args.quiet, "render") as progress:
        run = render(scene, fidelity, arch, progress=progress, **options)
        paths = run.save(out_dir)
    if not args.quiet:
        _print_render(scene, run.render_run, paths, replacing)
    return 0


def _plan_render(scene: Scene, args: argparse.Namespace, out_dir: str, turntable: bool) -> None:
    """Check every file this render will write (``--out`` and each file in it, a
    turntable's frames and GIF, ``--trace``) against the files it reads and the kinds
    already there (:func:`hwsim.core.paths.plan_outputs`), before the frame."""
    from hwsim.core.paths import FILE, plan_outputs
    from hwsim.run.output import render_outputs, scene_inputs
    from hwsim.run.turntable import turntable_outputs

    _load_machine(args)  # the files they name are read now, so counted as inputs
    inputs = [
        ("--volume" if key == "volume" and args.volume else key, path)
        for key, path in scene_inputs(scene)
    ]
    for flag in ("arch", "technology", "transfer"):  # named by their flags; what they
        value = getattr(args, flag, None)  # read in turn is recorded as they load
        if value and (value.endswith((".toml", ".npy")) or "/" in value):
            inputs.append((f"--{flag}", value))
    outputs = turntable_outputs(out_dir, args.frames) if turntable else render_outputs(out_dir)
    plan_outputs(inputs, [*outputs, ("--trace", args.trace, FILE)])


def _load_machine(args: argparse.Namespace) -> None:
    """Load ``--arch`` and ``--technology`` (each a name or a file) before the outputs
    are planned: every file they read (the arch file, the technology it names, each
    ``base`` of it) is recorded as an input (:func:`hwsim.core.paths.recording_reads`),
    and a bad one costs no frame.  The render loads them again from the cache."""
    from hwsim.energy import arch_technology
    from hwsim.run.fidelity import resolve_arch

    machine = resolve_arch(args.arch) if args.arch else None
    if machine is not None or args.technology:
        arch_technology(machine, args.technology)


def _render_options(args: argparse.Namespace) -> dict[str, Any]:
    """``render``'s keyword arguments from the command line (the split-frame ones only
    with ``--workers`` or ``--scheduler``)."""
    options = {
        "fidelity": args.fidelity,
        "arch": args.arch,
        "sampling": args.sampling,
        "trace": args.trace,
        "simulator": args.simulator,
        "extend": args.extend,
        "timing_only": args.timing_only,
        "technology": args.technology,
    }
    if args.workers is not None or args.scheduler is not None:
        options.update(workers=args.workers, scheduler=args.scheduler, bands=args.bands)
    elif args.bands is not None:
        raise InputError(
            "cuts a frame split across workers", key="--bands", allowed="with --workers"
        )
    return options


def _check_turntable(args: argparse.Namespace, options: dict[str, Any]) -> None:
    """A turntable renders whole frames in this process: no split frame, no timing only."""
    if "workers" in options:
        raise InputError(
            "a turntable renders its frames one after another in this process",
            key="--workers",
            allowed="one frame (no --frames or --turn)",
        )
    if args.timing_only:
        raise InputError(
            "a turntable writes its frames' images",
            key="--timing-only",
            allowed="one frame (no --frames or --turn)",
        )


def _print_transfer(scene: Scene) -> None:
    """Which transfer function classified the samples, and why (auto's choice)."""
    from hwsim.run.output import transfer_stats

    chosen = transfer_stats(scene)
    what = (
        f"{chosen['preset']} ({chosen['chosen_by']})" if chosen["preset"] else chosen["chosen_by"]
    )
    print(f"  transfer: {what}")


def _print_render(scene: Scene, run: Any, paths: dict[str, Path], replacing: bool) -> None:
    """The summary of one rendered frame: what, how fast, and where it was written."""
    for e in run.extensions:
        print(f"  what-if: {e['asked']} ({e['feature']}; {run.arch} has {e['machine']})")
    vol = run.volume
    image = "timed without its image"
    if run.image is not None:
        image = f"image {run.image.shape[1]}x{run.image.shape[0]}"
    print(
        f"{scene.name}: {vol.name} {'x'.join(map(str, vol.shape))} {vol.data.dtype}, "
        f"{scene.render.mode}, {run.fidelity}/{run.sampling}, {image}"
    )
    if run.scene.render.mode == "composite":  # the modes that classify samples
        _print_transfer(run.scene)
    print(
        f"  {run.samples:,} samples in {run.wall_seconds:.2f} s "
        f"({run.samples / max(run.wall_seconds, 1e-9) / 1e6:.2f} M samples/s wall)"
    )
    if run.cycles is not None:
        _print_timing(run)
    if run.split is not None:
        peaks = [b["peak_rss_bytes"] for b in run.split["bands"]]
        print(
            f"  split across {run.split['workers']} workers in {len(peaks)} bands: peak "
            f"memory {max(peaks) / 2**30:.2f} GB per worker, "
            f"{run.split['driver_peak_rss_bytes'] / 2**30:.2f} GB here"
        )
    if run.silicon is not None:
        e, a = run.silicon["energy"], run.silicon["area"]
        watts = f", {e['average_watts']:.2f} W at this frame rate" if e["average_watts"] else ""
        print(
            f"  energy {e['total_joules'] * 1e3:.3f} mJ/frame "
            f"({(e['per_sample_joules'] or 0) * 1e9:.2f} nJ/sample{watts}), area "
            f"{a['total_mm2']:.1f} mm^2 in {run.silicon['technology']['name']}"
        )
    note = " (no --out given: replaced the previous render there)" if replacing else ""
    names = [str(paths["png"]), paths["npy"].name] if "png" in paths else []
    print(f"  wrote {', '.join([*names, str(paths['stats'].name)])}{note}")


def _print_timing(run: Any) -> None:
    """The frame's simulated time, from the numbers ``stats.json`` holds (``frame_timing``):
    the machine's alone, and for a supervolume the frame's with the host's read back."""
    from hwsim.run.output import frame_timing

    t = frame_timing(run)
    bricked = "supervolume" in run.derived
    per_cycle = run.samples / run.cycles if run.cycles else 0.0
    print(
        f"  {run.cycles:,} cycles at {run.clock_hz / 1e6:g} MHz: "
        f"{t['machine_frame_seconds'] * 1e3:.3f} ms/frame, {t['machine_frames_per_second']:.1f} "
        f"fps{' on the machine' if bricked else ''}, {per_cycle:.2f} samples/cycle"
    )
    if bricked:
        bricks = run.derived["supervolume"]["bricks"]
        print(
            f"  with the host's read back of {bricks} bricks ({t['host_seconds'] * 1e3:.3f} ms, "
            f"blend not timed): {t['frame_seconds'] * 1e3:.3f} ms/frame, "
            f"{t['frames_per_second']:.1f} fps"
        )


def cmd_convert(args: argparse.Namespace) -> int:
    """A volume rewritten uncompressed, so that a frame split across workers can read it
    a part at a time: raw-encoded NRRD (keeps the spacing and HU units) or .npy."""
    import nrrd
    import numpy as np

    from hwsim.core.paths import FILE, atomic_write, plan_outputs
    from hwsim.volumes import read_volume

    out = args.out
    if not out.lower().endswith((".nrrd", ".npy")):
        raise InputError("unknown output type", source=out, key="OUT", allowed=".nrrd or .npy")
    plan_outputs([("IN", args.volume)], [("OUT", out, FILE)])
    volume = read_volume(args.volume)
    data = np.ascontiguousarray(volume.data)
    with atomic_write(out) as tmp:
        if out.lower().endswith(".npy"):
            with open(tmp, "wb") as fh:  # a file object: np.save adds no suffix
                np.save(fh, data)
            kept = "spacing not kept: .npy has none"
        else:
            header = {"encoding": "raw", "spacings": list(volume.spacing[::-1])}
            if volume.units == "HU":
                header["content"] = f"{volume.name} (Hounsfield units)"
            nrrd.write(str(tmp), data, header=header, index_order="C")
            kept = f"spacing {volume.spacing}"
    shape = "x".join(map(str, volume.shape))
    print(f"wrote {out}: {shape} {data.dtype}, {kept}")
    return 0


def _turntable(scene, args: argparse.Namespace, out_dir: str, options: dict) -> int:
    """``hwsim render --frames N [--turn DEG]``: a turntable, each frame written as it
    ends and let go (hwsim.run.turntable.stream_turntable)."""
    from hwsim.run.turntable import stream_turntable, turntable_stats

    turn = args.turn if args.turn is not None else 360.0 / max(args.frames, 1)
    with progress_bar(args.quiet, "frames") as progress:
        first, frames, paths = stream_turntable(
            scene, args.frames, turn, out_dir, progress=progress, **options
        )
    if not args.quiet:
        stats = turntable_stats(frames, turn)
        print(
            f"{scene.name}: {len(frames)} frames, {turn:g} degrees apart, "
            f"{first.fidelity}/{first.sampling}: first frame "
            f"{first.wall_seconds:.2f} s, then {stats['median_frame_wall_seconds']:.3f} s "
            "per frame (median)"
        )
        print(f"  wrote {paths['gif']} and {len(frames)} frames in {paths['frames']}")
    return 0
