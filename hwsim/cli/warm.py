"""``hwsim warm``: compile the frame kernels once, so that the first render starts fast.

numba compiles a kernel on its first call and keeps it in its on-disk cache (the
``__pycache__`` folder beside the kernel's module, or ``NUMBA_CACHE_DIR``); a later
process loads it in milliseconds.  With a cold cache the first render of each rung and
machine waits for its compile (a VolumePro 500 functional render: about 40 s cold, 3 s
warm).  ``hwsim warm`` renders a tiny frame of every built-in scene at the golden rung
and of the default scene on every built-in machine at each rung that runs compiled
kernels (functional, cycle), so the kernels those renders use are compiled and cached.
With a warm cache it only loads them.  ``./dev run`` runs it after installing.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from typing import Any

from hwsim.cli.progress import progress_bar
from hwsim.core.errors import HwsimError

__all__ = ["add_warm_parser", "cmd_warm", "warm_jobs"]

#: The side of the warming frames' image and phantoms: the kernels compiled do not depend
#: on sizes, only on types and the machine's formats.
TINY = 12
#: The rungs whose frames run compiled kernels on a machine (golden runs them too).
COMPILED_RUNGS = ("functional", "cycle")


def add_warm_parser(sub) -> None:
    w = sub.add_parser(
        "warm", help="compile the frame kernels once (first run only), so renders start fast"
    )
    w.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def warm_jobs() -> list[tuple[str, str, str | None]]:
    """The warming renders ``(scene, fidelity, arch)``: every built-in scene at the golden
    rung, and the default scene on every built-in machine at each of
    :data:`COMPILED_RUNGS` that models it."""
    from hwsim.run.fidelity import builtin_archs, machine_rungs
    from hwsim.spec.scene import builtin_scenes

    jobs: list[tuple[str, str, str | None]] = [(n, "golden", None) for n in builtin_scenes()]
    for name, arch in builtin_archs().items():
        rungs = machine_rungs(arch)
        jobs += [("head", rung, name) for rung in COMPILED_RUNGS if rung in rungs]
    return jobs


def _tiny(scene: Any) -> Any:
    """``scene`` with a :data:`TINY` image and phantom (a file volume is kept)."""
    view = dataclasses.replace(scene.view, width=TINY, height=TINY)
    volume = scene.volume
    if volume.phantom is not None:
        params = dict(volume.params)
        if "size" in params:
            params["size"] = TINY
        volume = dataclasses.replace(volume, params=tuple(params.items()))
    return scene.replace(view=view, volume=volume)


def cmd_warm(args: argparse.Namespace) -> int:
    """Run :func:`warm_jobs`; print how long it took and any render that failed."""
    from hwsim.run.fidelity import render
    from hwsim.spec.scene import load_scene

    start = time.perf_counter()
    jobs = warm_jobs()
    failed = []
    with progress_bar(args.quiet, "warming kernels") as progress:
        for k, (name, fidelity, arch) in enumerate(jobs):
            if progress is not None:
                progress(k, len(jobs), f"{name} {fidelity} {arch or ''}".strip())
            try:
                render(_tiny(load_scene(name)), fidelity=fidelity, arch=arch)
            except HwsimError as exc:  # a tiny frame a machine refuses: its kernels stay cold
                failed.append(f"{name} {fidelity} {arch}: {exc}")
        if progress is not None:
            progress(len(jobs), len(jobs))
    for line in failed:
        print(f"hwsim: warm: skipped {line}", file=sys.stderr)
    if not args.quiet:
        seconds = time.perf_counter() - start
        print(f"kernels warm: {len(jobs) - len(failed)} renders in {seconds:.1f} s")
    return 0
