"""The speed table's measurements, one function per row (or pair of rows): what each
compares, timed in alternation (A, B, A, B, ...) so that a change of machine load falls
on both.  ``benchmarks/speed_table.py`` plans and runs them, ``speed_report.py`` prints
them; the module docstring of ``speed_table.py`` says what every row means.
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

from hwsim.core import env
from hwsim.core.threads import using as using_threads

REPO = Path(__file__).resolve().parents[1]
DATA = env.value("HWSIM_SHARED_DATA") or REPO.parent / "shared" / "data"
CT = DATA / "ct_cranium.nrrd"
#: The machines of the cycle, timing-only and memory rows.
MACHINES = ("cube4", "em-cube", "volumepro500", "volumepro1000", "vizard2")
TURN = 5.0


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def _alternate(repeats: int, runs: dict[str, Callable[[], Any]]) -> dict[str, list[float]]:
    """Seconds of every run, ``repeats`` rounds of A, B, ... in turn."""
    times: dict[str, list[float]] = {k: [] for k in runs}
    for _ in range(repeats):
        for name, fn in runs.items():
            times[name].append(_timed(fn)[0])
    return times


def _into(results: list[Any], fn: Callable[..., Any], *args: Any) -> None:
    results.append(fn(*args))


def _median(times: dict[str, list[float]]) -> dict[str, float]:
    return {k: statistics.median(v) for k, v in times.items()}


# ----------------------------------------------------------------- golden vs VTK


def _ct_scene(image: int):
    from benchmarks.vtk_reference import VTK_EARLY_TERMINATION
    from hwsim.spec.scene import VolumeSpec, load_scene

    head = load_scene("head")
    return dataclasses.replace(
        head,
        volume=VolumeSpec(path=str(CT)),
        view=dataclasses.replace(head.view, width=image, height=image),
        render=dataclasses.replace(head.render, early_termination=VTK_EARLY_TERMINATION),
    )


def _vtk_caster(scene, volume, transfer, threads: int):
    from benchmarks.bench_golden import _vtk_kwargs
    from benchmarks.vtk_reference import VtkRayCaster

    return VtkRayCaster(**_vtk_kwargs(volume, transfer, scene), threads=threads)


def golden_vs_vtk_first(repeats: int, image: int = 256) -> dict[str, Any]:
    """First frames, golden (file read + render) and VTK (pipeline + first render)."""
    from hwsim.golden import render_golden
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import load_volume

    scene = _ct_scene(image)
    decoded = load_volume(scene.volume)
    transfer = resolve_transfer(scene.transfer, decoded)
    render_golden(scene, decoded, transfer)  # compiled code loaded, as in any later run

    def golden() -> None:
        volume = load_volume(scene.volume)  # a new volume: nothing derived is cached
        render_golden(scene, volume, resolve_transfer(scene.transfer, volume))

    def vtk(threads: int) -> Callable[[], None]:
        def first() -> None:
            caster = _vtk_caster(scene, decoded, transfer, threads)
            caster.render()
            caster.close()

        return first

    vtk(1)()  # VTK's own first-use costs (shaders, window) out of the timings
    runs: dict[str, Callable[[], Any]] = {}
    for threads in (1, 2):
        runs[f"golden_{threads}t"] = _with_threads(threads, golden)
        runs[f"vtk_{threads}t"] = vtk(threads)
    med = _median(_alternate(repeats, runs))
    return {
        "value": med["vtk_1t"] / med["golden_1t"],
        "two_threads": med["vtk_2t"] / med["golden_2t"],
        "seconds": med,
    }


def golden_vs_vtk_rotation(frames: int, image: int = 256) -> dict[str, Any]:
    """Later frames of a rotation: the median of frames 2..N of each renderer."""
    from hwsim.golden import render_golden
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import load_volume

    scene = _ct_scene(image)
    volume = load_volume(scene.volume)
    transfer = resolve_transfer(scene.transfer, volume)
    casters = {t: _vtk_caster(scene, volume, transfer, t) for t in (1, 2)}
    times: dict[str, list[float]] = {f"{w}_{t}t": [] for w in ("golden", "vtk") for t in (1, 2)}
    samples = 0
    for k in range(frames):
        az = scene.view.azimuth + TURN * k
        view = dataclasses.replace(scene.view, azimuth=az)
        for threads in (1, 2):
            with using_threads(threads):
                moved = scene.replace(view=view)
                s, result = _timed(lambda m=moved: render_golden(m, volume, transfer))
            samples = result.samples
            casters[threads].set_view(az, scene.view.elevation)
            v = casters[threads].render()
            if k:  # frame 1 pays the set-up
                times[f"golden_{threads}t"].append(s)
                times[f"vtk_{threads}t"].append(v)
    for caster in casters.values():
        caster.close()
    med = _median(times)
    return {
        "value": med["vtk_1t"] / med["golden_1t"],
        "two_threads": med["vtk_2t"] / med["golden_2t"],
        "seconds": med,
        "golden_samples_last_frame": samples,
        "frames": frames,
    }


def _with_threads(threads: int, fn: Callable[[], Any]) -> Callable[[], Any]:
    def run() -> Any:
        with using_threads(threads):
            return fn()

    return run


# ----------------------------------------------------------------- functional rows


def functional_vs_volpack(frames: int, repeats: int) -> dict[str, Any]:
    """VolPack's ``rendervolume`` against the functional rung, alternating runs."""
    import tempfile

    from benchmarks import volpack_reference as vp

    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="volpack-") as tmp:
        work = vp.build(vp.EXAMPLES, Path(tmp))
        rounds = {"volpack": [], "functional_1t": [], "functional_2t": []}
        for _ in range(repeats):
            rounds["volpack"].append(vp.volpack_frame_seconds(work, frames, 1)["seconds_per_frame"])
            for threads in (1, 2):
                with using_threads(threads):
                    hw = vp.hwsim_frame_seconds("volumepro500", frames, 1, 256)
                rounds[f"functional_{threads}t"].append(hw["seconds_per_frame"])
    med = _median(rounds)
    out.update(
        value=med["volpack"] / med["functional_1t"],
        two_threads=med["volpack"] / med["functional_2t"],
        seconds_per_frame=med,
    )
    return out


def _machine_case(arch_name: str, n: int, image: int | None = None):
    from hwsim.golden import make_plan
    from hwsim.run.fidelity import resolve_arch
    from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import make_phantom
    from models.frame import frame_of

    arch = resolve_arch(arch_name)
    volume = make_phantom("head", size=n)
    side = image or n
    view = ViewSpec(azimuth=30, elevation=15, width=side, height=side, zoom=1.3)
    scene = Scene(transfer=TransferSpec(preset="ct"), view=view)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, arch.order)
    return arch, volume, scene, tf, frame_of(scene, volume, tf, arch, plan)


def functional_vs_golden(repeats: int, size: int = 128) -> dict[str, Any]:
    """Golden at the machine's sample positions against the functional rung (VP500)."""
    from hwsim.golden import render_golden
    from models.functional import render_functional

    arch, volume, scene, tf, frame = _machine_case("volumepro500", size, 256)
    golden = _with_threads(1, lambda: render_golden(scene, volume, tf, sampling=arch.order))
    functional = _with_threads(1, lambda: render_functional(frame))
    golden(), functional()
    med = _median(_alternate(repeats, {"golden": golden, "functional": functional}))
    return {"value": med["golden"] / med["functional"], "seconds": med, "size": size}


# ----------------------------------------------------------------- cycle rows


def cycle_and_timing_only(sizes: Sequence[int], repeats: int) -> tuple[dict, dict]:
    """Every machine and size: the cycle rung and the timing-only transaction rung in
    alternation (one thread); returns the ``cycle_samples_per_s`` and
    ``timing_only_vs_cycle`` rows."""
    from hwsim.engine.metrics import issued_samples
    from models.cycle import render_cycle
    from models.transaction import timing_only

    cases = []
    for arch_name in MACHINES:
        for n in sizes:
            arch, volume, scene, tf, frame = _machine_case(arch_name, n)
            if any(n > m for m in arch.max_volume):
                cases.append({"arch": arch_name, "size": n, "status": "over the machine's memory"})
                continue
            cycle_runs: list[Any] = []
            alone: list[Any] = []
            runs = {
                "cycle": _with_threads(1, partial(_into, cycle_runs, render_cycle, frame)),
                "timing_only": _with_threads(1, partial(_into, alone, timing_only, frame)),
            }
            # Warm-up, neither run counted: compiled loops (VIZARD II's ray loop, the SDRAM
            # scheduler) loaded or compiled, per-volume maps and memory images built.
            runs["cycle"](), runs["timing_only"]()
            cycle_runs.clear(), alone.clear()
            med = _median(_alternate(repeats, runs))
            run = cycle_runs[-1]
            issued = issued_samples(run.counters, run.samples)
            cases.append(
                {
                    "arch": arch_name,
                    "size": n,
                    "samples": run.samples,
                    "issued_samples": issued,
                    "cycles": run.cycles,
                    "cycle_seconds": med["cycle"],
                    "cycle_samples_per_s": issued / med["cycle"],
                    "timing_only_seconds": med["timing_only"],
                    "timing_only_vs_cycle": med["cycle"] / med["timing_only"],
                    "timing_only_cycle_error": (alone[-1].cycles - run.cycles) / run.cycles,
                }
            )
    done = [c for c in cases if "cycle_seconds" in c]
    speed = {"value": min(c["cycle_samples_per_s"] for c in done), "cases": cases}
    ratio = {"value": min(c["timing_only_vs_cycle"] for c in done), "cases": cases}
    return speed, ratio


_MEMORY_SCRIPT = """
import sys; sys.path.insert(0, {root!r})
from benchmarks.speed_rows import _machine_case
from hwsim.run.fidelity import render
arch, volume, scene, tf, frame = _machine_case({arch!r}, {n}, {image})
with open('/proc/self/clear_refs', 'w') as f:
    f.write('5')  # VmHWM from here: the frame, not building the phantom
run = render(scene, fidelity='cycle', arch=arch, volume=volume)
hwm = [l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM:')][0]
print(volume.data.nbytes, hwm, run.samples, run.cycles)
"""


def cycle_512_peak(n: int, image: int | None = None) -> dict[str, Any]:
    """Peak resident set of one ``n^3`` cycle frame per machine, each in a new process
    (``VmHWM`` reset after the phantom is built; ``hwsim.run.fidelity.render``, so VolumePro
    500 renders a supervolume as its boards did)."""
    cases = []
    for arch_name in MACHINES:
        code = _MEMORY_SCRIPT.format(root=str(REPO), arch=arch_name, n=n, image=image)
        env = {**os.environ, "HWSIM_THREADS": "1"}
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
        wall = time.perf_counter() - start
        if done.returncode != 0:
            tail = (done.stderr.strip().splitlines() or ["?"])[-1]
            # A machine that cannot hold the volume refuses it, as its boards did: not a
            # failure of the simulator, and not part of the row's value.
            status = "refused by the machine" if "InputError" in tail else "failed"
            cases.append({"arch": arch_name, "size": n, "status": status, "note": tail})
            continue
        vol, hwm_kib, samples, cycles = (int(x) for x in done.stdout.split())
        cases.append(
            {
                "arch": arch_name,
                "size": n,
                "volume_bytes": vol,
                "peak_rss_bytes": hwm_kib * 1024,
                "peak_over_volume": hwm_kib * 1024 / vol,
                "samples": samples,
                "cycles": cycles,
                "wall_seconds": wall,
            }
        )
    done_cases = [c for c in cases if "peak_rss_bytes" in c]
    value = max(c["peak_rss_bytes"] for c in done_cases) if done_cases else None
    failed = any(c["status"] == "failed" for c in cases if "status" in c)
    return {"value": value, "cases": cases, **({"status": "failed"} if failed else {})}


def threads_2_vs_1(repeats: int) -> dict[str, Any]:
    """One frame on one thread and on two, alternating: golden (CT 256^2 when present,
    else the head phantom), functional and cycle (VolumePro 500, head 128^3 to 256^2)."""
    from hwsim.golden import render_golden
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import load_volume, make_phantom
    from models.cycle import render_cycle
    from models.functional import render_functional

    if CT.is_file():
        scene = _ct_scene(256)
        volume = load_volume(scene.volume)
    else:
        from benchmarks.bench_golden import make_scene

        scene, volume = make_scene(256, 256, 256, 1.0), make_phantom("head", size=256)
    tf = resolve_transfer(scene.transfer, volume)
    arch, _, _, _, frame = _machine_case("volumepro500", 128, 256)
    work = {
        "golden": lambda: render_golden(scene, volume, tf),
        "functional": lambda: render_functional(frame),
        "cycle": lambda: render_cycle(frame),
    }
    per: dict[str, Any] = {}
    for name, fn in work.items():
        fn()
        med = _median(_alternate(repeats, {"1t": _with_threads(1, fn), "2t": _with_threads(2, fn)}))
        per[name] = {"seconds": med, "speedup": med["1t"] / med["2t"]}
    return {"value": min(p["speedup"] for p in per.values()), "rungs": per}
