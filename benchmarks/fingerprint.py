"""Fingerprints of random renders, for checking that a refactor changes no result.

Renders ``--count`` random small scenes (phantom, size, view, projection, image, mode,
lighting, sample spacing drawn from a seeded generator) on every built-in machine at the
functional, transaction and cycle rungs, and writes one line per render: the SHA-256 of
the image bytes, the cycle count, and the SHA-256 of the sorted counters but the
wall-clock ones (or the error a rung raised, file paths cut to their names).  Run it on
the tree before and after a change and compare the files::

    python -m benchmarks.fingerprint --count 300 --out before.jsonl   # old tree
    python -m benchmarks.fingerprint --count 300 --out after.jsonl    # new tree
    cmp before.jsonl after.jsonl

Wall times are not recorded, so equal trees give byte-identical files.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import re
from pathlib import Path

import numpy as np

RUNGS = ("functional", "transaction", "cycle")
PHANTOMS = ("ball", "head", "marschner-lobb")
MODES = ("composite", "composite", "mip", "iso")
#: The transaction rung's ``transaction.*_seconds`` counters time the model itself.
WALL_CLOCK_SUFFIX = "_seconds"


def random_scene(rng: np.random.Generator):
    """One small random scene and a short description of it."""
    from hwsim.spec.scene import TransferSpec, VolumeSpec, load_scene

    base = load_scene("head")
    phantom = str(rng.choice(PHANTOMS))
    size = int(rng.integers(8, 24))
    width, height = (int(v) for v in rng.integers(6, 20, size=2))
    azimuth, elevation = float(rng.integers(-180, 180)), float(rng.integers(-80, 80))
    mode = str(rng.choice(MODES))
    projection = "perspective" if rng.random() < 0.25 else "parallel"
    view = dataclasses.replace(
        base.view,
        azimuth=azimuth,
        elevation=elevation,
        width=width,
        height=height,
        projection=projection,
    )
    render = dataclasses.replace(
        base.render,
        mode=mode,
        lighting=bool(rng.integers(2)),
        sample_spacing=float(rng.choice([0.5, 1.0, 1.0, 2.0])),
    )
    # The ct preset named, not the head scene's auto: every phantom keeps the preset its
    # fingerprints were first recorded with (auto would give the ball and Marschner-Lobb
    # the warm ramp).
    scene = base.replace(
        volume=VolumeSpec(phantom=phantom, params=(("size", size),)),
        transfer=TransferSpec(preset="ct"),
        view=view,
        render=render,
    )
    what = f"{phantom}:{size} {width}x{height} {projection} {azimuth:g},{elevation:g} {mode}"
    return scene, what


def fingerprint(scene, fidelity: str, arch: str) -> dict:
    from hwsim.core.errors import HwsimError
    from hwsim.run.fidelity import render

    try:  # what-ifs included: a refactor must keep those bits too
        run = render(scene, fidelity=fidelity, arch=arch, extend=True)
    except HwsimError as exc:
        # Paths cut to file names: a refactor may move the architecture files.
        return {"error": re.sub(r"\S*/([^/\s]+)", r"\1", f"{type(exc).__name__}: {exc}")}
    # The transaction rung's own wall times are measurements, not results.
    kept = {k: v for k, v in run.counters.items() if not k.endswith(WALL_CLOCK_SUFFIX)}
    counters = json.dumps(kept, sort_keys=True, default=str)
    return {
        "image": hashlib.sha256(np.ascontiguousarray(run.image).tobytes()).hexdigest()[:16],
        "cycles": run.cycles,
        "counters": hashlib.sha256(counters.encode()).hexdigest()[:16],
    }


def main() -> None:
    from hwsim.run.fidelity import builtin_archs

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=300, help="renders in all")
    parser.add_argument("--seed", type=int, default=15)
    parser.add_argument("--out", type=Path, required=True, help="JSON lines file")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    archs = sorted(builtin_archs())
    with open(args.out, "w") as fh:
        for i in range(args.count):
            scene, what = random_scene(rng)
            arch = archs[i % len(archs)]
            fidelity = RUNGS[(i // len(archs)) % len(RUNGS)]
            row = {"i": i, "arch": arch, "rung": fidelity, "scene": what}
            row.update(fingerprint(scene, fidelity, arch))
            fh.write(json.dumps(row) + "\n")
            fh.flush()


if __name__ == "__main__":
    main()
