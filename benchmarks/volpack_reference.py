"""VolPack's shear-warp renderer as the speed reference of the functional rung.

Usage::

    .venv/bin/python benchmarks/volpack_reference.py [--frames 10] [--repeats 3]
                                                     [--arch volumepro500] [--out FILE.json]

VolPack (Lacroute & Levoy's shear-warp library) is what a user of a software volume
renderer of the VolumePro era would pick; Debian's ``libvolpack1-dev`` ships the library
and its example programs with their data, the MR scan ``brainsmall.den`` (128 x 128 x 84,
8 bits) that ``../shared/data/mr_brainsmall.nrrd`` holds too.  When the package is
installed, this harness copies the examples into a scratch folder, builds them with the
Makefile beside them (``gcc -O2``), makes the unclassified volume once (``makevolume``)
and times ``rendervolume N``: N frames of 256 x 256, composite with Phong shading from
its precomputed normals and opacity from density and gradient ramps, early ray
termination at 0.95, the view turned 5 degrees about y between frames, each frame
written as a PGM.  Without the package it says so and reports ``volpack: null``.

hwsim's functional rung renders the same file on ``--arch`` (VolumePro 500 by default:
no early termination, as that machine had none) at 256 x 256, composite with Phong
shading, the ``mr`` preset, turning 5 degrees a frame, on one loaded volume (its caches
kept between frames, as VolPack keeps its volume).  For both, a frame costs the time of
N frames minus the time of one frame, divided by N - 1 (loading and set-up cancel out);
each is the median of ``--repeats`` runs.  ``ratio`` is VolPack's seconds per frame over
hwsim's (the issue's goal: at least 0.1).  The two renderers do not compute the same
image (different transfer functions and arithmetic): this compares what each costs a
frame of the same volume, view sequence and image size.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import gzip
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.core import env

__all__ = ["EXAMPLES", "GOAL_RATIO", "volpack_available", "volpack_frame_seconds", "run", "main"]

#: Where Debian's libvolpack1-dev installs the example programs and their data.
EXAMPLES = Path("/usr/share/doc/libvolpack1-dev/examples")
HEADER = Path("/usr/include/volpack.h")
GOAL_RATIO = 0.1
REPO = Path(__file__).resolve().parents[1]
#: The MR scan beside the clone (``HWSIM_SHARED_DATA`` overrides the folder, as in tests).
VOLUME = (env.value("HWSIM_SHARED_DATA") or REPO.parent / "shared" / "data") / (
    "mr_brainsmall.nrrd"
)
TURN = 5.0  # degrees per frame, as rendervolume turns


def volpack_available(examples: Path = EXAMPLES, volume: Path = VOLUME) -> str | None:
    """None when VolPack can be built and run here on ``volume``'s scan, else why not, in
    one line naming what to install (``hwsim bench`` skips its row with it)."""
    if not HEADER.exists() or not examples.is_dir():
        return "needs VolPack (apt-get install libvolpack1-dev; ./dev test installs it)"
    for tool in ("gcc", "make"):
        if shutil.which(tool) is None:
            return f"needs {tool} to build VolPack's examples (apt-get install {tool})"
    if not volume.is_file():
        return f"needs {volume} (the shared data beside the clone)"
    return None


def build(examples: Path, work: Path) -> Path:
    """Copy the examples into ``work``, unpack, build them and make the volume file."""
    for item in examples.iterdir():
        target = work / item.name.removesuffix(".gz")
        if item.name.endswith(".gz"):
            with gzip.open(item) as src, open(target, "wb") as dst:
                shutil.copyfileobj(src, dst)
        else:
            shutil.copy(item, target)
    subprocess.run(
        ["make", "-s", "makevolume", "rendervolume"], cwd=work, check=True, capture_output=True
    )
    subprocess.run(["./makevolume"], cwd=work, check=True, capture_output=True)
    return work


def _time_run(work: Path, frames: int) -> float:
    start = time.perf_counter()
    subprocess.run(["./rendervolume", str(frames)], cwd=work, check=True, capture_output=True)
    return time.perf_counter() - start


def volpack_frame_seconds(work: Path, frames: int, repeats: int) -> dict[str, Any]:
    """Seconds per frame of ``rendervolume`` (N frames minus one, over N - 1)."""
    one = statistics.median(_time_run(work, 1) for _ in range(repeats))
    many = statistics.median(_time_run(work, frames) for _ in range(repeats))
    return {
        "one_frame_run_seconds": one,
        "n_frame_run_seconds": many,
        "seconds_per_frame": (many - one) / (frames - 1),
    }


def hwsim_frame_seconds(
    arch: str, frames: int, repeats: int, image: int, path: Path = VOLUME
) -> dict[str, Any]:
    """The functional rung's seconds per frame over the same kind of rotation."""
    import dataclasses

    from hwsim.run.fidelity import render, resolve_arch
    from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
    from hwsim.volumes import load_volume

    spec = VolumeSpec(path=str(path))
    volume = load_volume(spec, REPO)
    machine = resolve_arch(arch)
    base = Scene(
        volume=spec,
        transfer=TransferSpec(preset="mr"),
        view=ViewSpec(azimuth=130.0, elevation=-15.0, width=image, height=image, zoom=1.0),
        render=RenderSpec(mode="composite"),
    )

    def frames_run(n: int) -> float:
        start = time.perf_counter()
        for k in range(n):
            view = dataclasses.replace(base.view, azimuth=base.view.azimuth + TURN * k)
            render(base.replace(view=view), fidelity="functional", arch=machine, volume=volume)
        return time.perf_counter() - start

    frames_run(1)  # warm-up: kernels compiled, per-volume caches filled
    one = statistics.median(frames_run(1) for _ in range(repeats))
    many = statistics.median(frames_run(frames) for _ in range(repeats))
    return {
        "arch": arch,
        "one_frame_run_seconds": one,
        "n_frame_run_seconds": many,
        "seconds_per_frame": (many - one) / (frames - 1),
    }


def run(
    *, frames: int = 10, repeats: int = 3, arch: str = "volumepro500", image: int = 256,
    examples: Path = EXAMPLES, volume: Path = VOLUME,
) -> dict[str, Any]:  # fmt: skip
    """Both renderers' seconds per frame and their ratio (see the module docstring)."""
    if frames < 2:
        raise ValueError("frames must be at least 2: a frame is N frames minus one")
    report: dict[str, Any] = {
        "benchmark": "volpack_reference",
        "frames": frames,
        "repeats": repeats,
        "image": [image, image],
        "turn_degrees": TURN,
        "volume": volume.name,
        "platform": platform.platform(),
        "goal_ratio": GOAL_RATIO,
    }
    missing = volpack_available(examples, volume)
    report["volpack_missing"] = missing
    report["volpack"] = None
    if missing is None:
        with tempfile.TemporaryDirectory(prefix="volpack-") as tmp:
            work = build(examples, Path(tmp))
            report["volpack"] = volpack_frame_seconds(work, frames, repeats)
    report["hwsim"] = hwsim_frame_seconds(arch, frames, repeats, image, volume)
    if report["volpack"] is not None:
        vp, hw = report["volpack"]["seconds_per_frame"], report["hwsim"]["seconds_per_frame"]
        report["ratio"] = vp / hw if hw > 0 else None
    else:
        report["ratio"] = None
    return report


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--arch", default="volumepro500")
    parser.add_argument("--image", type=int, default=256)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    if not VOLUME.exists():
        print(f"volpack_reference: {VOLUME} is missing (../shared/data)", file=sys.stderr)
        return 2
    report = run(frames=args.frames, repeats=args.repeats, arch=args.arch, image=args.image)
    if report["volpack_missing"]:
        print(f"volpack_reference: {report['volpack_missing']}; timing hwsim only", file=sys.stderr)
    vp = report["volpack"]
    hw = report["hwsim"]["seconds_per_frame"]
    line = f"hwsim functional ({args.arch}) {hw * 1e3:.1f} ms/frame"
    if vp is not None:
        line += (
            f", VolPack {vp['seconds_per_frame'] * 1e3:.1f} ms/frame: ratio {report['ratio']:.3f}"
        )
        line += f" (goal >= {GOAL_RATIO})"
    print(line)
    if args.out is not None:
        write_report(report, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
