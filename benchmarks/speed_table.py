"""Issue 18's speed table, every row measured in one run: hwsim against the software users
would pick instead (VTK, VolPack), the cycle rung's speed on every machine, the
timing-only transaction rung against it, a 512^3 cycle frame's peak memory, and what a
second core buys.

Usage::

    .venv/bin/python benchmarks/speed_table.py [--rows NAME ...] [--sizes 128 256]
        [--memory-size 512] [--repeats 3] [--out benchmarks/results/speed-table.json]

``hwsim bench`` runs the same rows (this module is its harness).  Each row times the
things it compares in alternation (A, B, A, B, ...), so a change of machine load falls on
both; the load average is recorded before and after every row.  Headline figures use
**one thread** for hwsim and for VTK (``HWSIM_THREADS=1``, ``SetNumberOfThreads(1)``);
the two-thread figures sit beside them.  Benchmarks assert nothing (conventions item 11).

A row that needs more than the run install (:data:`REQUIRES`: VTK from the ``bench``
extra, VolPack from apt, the shared data) is checked before any row is measured and,
when that is missing, ``skipped`` with a one-line reason naming what to install;
``--no-vtk`` skips the VTK rows.  A row that raises is ``failed`` with its error in one
line and the other rows still run (the exit status is then 1).

======================  ========================================================  =======
row                     value                                                     goal
======================  ========================================================  =======
golden_vs_vtk_first     VTK first frame s / golden first frame s: real CT, 256^2  >= 0.5
golden_vs_vtk_rotation  the same over later frames of a 5-degree rotation         >= 0.1
functional_vs_volpack   VolPack s/frame / functional (volumepro500) s/frame       >= 0.1
functional_vs_golden    golden s / functional s, the machine's sample positions   >= 2
cycle_samples_per_s     the slowest machine's cycle-rung samples per second       >= 5 M
timing_only_vs_cycle    the smallest cycle s / timing-only transaction s          >= 10
cycle_512_peak_bytes    the largest peak resident set of a 512^3 cycle frame      <= 1.5 G
threads_2_vs_1          the smallest 1-thread s / 2-thread s (golden, functional) >= 1.7
======================  ========================================================  =======

The golden and VTK frames: ``../shared/data/ct_cranium.nrrd`` (256 x 256 x 108 int16), the
``ct`` preset, composite with one-light Phong (the built-in ``head`` scene's view and
material), 256 x 256, VTK's built-in early ray termination (accumulated opacity 0.9922)
given to the golden renderer too.  A *first frame* is everything after the process has
started and imported: golden reads and decodes the file and renders (its gradients and
block ranges computed for the new volume); VTK builds its pipeline on the decoded array
and renders its first frame (which computes and encodes its gradients).  A *later frame*
is the median of frames 2..N of a rotation by 5 degrees a frame, each renderer keeping
its per-volume data.
"""

from __future__ import annotations

import argparse
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

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.core import env
from hwsim.core.threads import using as using_threads
from hwsim.studies.bench import TABLE_GOALS as GOALS
from hwsim.studies.bench import one_line, status_text

REPO = Path(__file__).resolve().parents[1]
DATA = env.value("HWSIM_SHARED_DATA") or REPO.parent / "shared" / "data"
CT = DATA / "ct_cranium.nrrd"
#: The machines of the cycle, timing-only and memory rows.
MACHINES = ("cube4", "em-cube", "volumepro500", "volumepro1000", "vizard2")
TURN = 5.0

ROWS = tuple(GOALS)  # the table's rows, in order


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
            runs["timing_only"]()  # warm-up: compiled SDRAM scheduler, per-volume maps
            med = _median(_alternate(repeats, runs))
            run = cycle_runs[-1]
            cases.append(
                {
                    "arch": arch_name,
                    "size": n,
                    "samples": run.samples,
                    "cycles": run.cycles,
                    "cycle_seconds": med["cycle"],
                    "cycle_samples_per_s": run.samples / med["cycle"],
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
from benchmarks.speed_table import _machine_case
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


# ----------------------------------------------------------------- what rows need


def _needs_vtk() -> str | None:
    from benchmarks.vtk_reference import vtk_missing

    return vtk_missing()


def _needs_ct() -> str | None:
    return None if CT.is_file() else f"needs {CT} (the shared data beside the clone)"


def _needs_volpack() -> str | None:
    from benchmarks.volpack_reference import volpack_available

    return volpack_available()


#: What a row needs beyond the run install (``pip install -e .[run]``), each a check that
#: returns why it is missing (one line naming what to install) or None.  The other rows
#: need nothing more (``threads_2_vs_1`` renders the CT scan when it is there, else the
#: head phantom; it borrows only VTK's early-termination constant, not VTK).
REQUIRES: dict[str, tuple[Callable[[], str | None], ...]] = {
    "golden_vs_vtk_first": (_needs_vtk, _needs_ct),
    "golden_vs_vtk_rotation": (_needs_vtk, _needs_ct),
    "functional_vs_volpack": (_needs_volpack,),
}
#: The rows ``vtk=False`` (``--no-vtk``) skips: every use of VTK.
VTK_ROWS = ("golden_vs_vtk_first", "golden_vs_vtk_rotation")


def plan(rows: Sequence[str] = ROWS, *, vtk: bool = True) -> list[tuple[str, str | None]]:
    """The rows of ``rows`` in the table's order, each with why it will be skipped
    (``None``: it runs), found before any row is measured."""
    unknown = set(rows) - set(ROWS)
    if unknown:
        raise ValueError(f"unknown rows {sorted(unknown)}; rows are {', '.join(ROWS)}")
    out = []
    for name in (r for r in ROWS if r in rows):
        why = "--no-vtk" if not vtk and name in VTK_ROWS else None
        for check in REQUIRES.get(name, ()) if why is None else ():
            why = check()
            if why is not None:
                break
        out.append((name, why))
    return out


# ----------------------------------------------------------------- the table


def _row(name: str, measure: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """Row ``name`` measured: its value, goal and whether it is met; ``failed`` with the
    error in one line when the measurement raised (the other rows still run)."""
    goal, better, unit, definition = GOALS[name]
    before = list(os.getloadavg())
    start = time.perf_counter()
    try:
        row = measure()
    except Exception as exc:  # a failed row is reported, the table goes on
        row = {"status": "failed", "error": one_line(exc)}
    row.setdefault("status", "ok" if row.get("value") is not None else "not available")
    value = row.get("value")
    met = None
    if value is not None and row["status"] == "ok":
        met = value >= goal if better == "higher" else value <= goal
    return {
        "row": name,
        **row,
        "goal": goal,
        "better": better,
        "unit": unit,
        "definition": definition,
        "goal_met": met,
        "wall_seconds": time.perf_counter() - start,
        "load_average_before": before,
        "load_average_after": list(os.getloadavg()),
    }


def skipped(name: str, why: str) -> dict[str, Any]:
    """The record of row ``name`` skipped because of ``why`` (a missing extra or a flag)."""
    goal, better, unit, definition = GOALS[name]
    return {
        "row": name,
        "status": "skipped",
        "note": why,
        "goal": goal,
        "better": better,
        "unit": unit,
        "definition": definition,
        "goal_met": None,
    }


def run(
    rows: Sequence[str] = ROWS,
    *,
    vtk: bool = True,
    sizes: Sequence[int] = (128, 256),
    memory_size: int = 512,
    repeats: int = 3,
    frames: int = 10,
    log: Callable[[str], None] = lambda m: None,
    on_row: Callable[[str], None] = lambda name: None,
    out: list[dict[str, Any]] | None = None,
) -> list[dict[str, Any]]:
    """The rows named in ``rows`` (in the table's order), as JSON-ready dicts.

    A row whose requirement is missing (:data:`REQUIRES`; ``vtk`` false: every VTK row)
    is ``skipped`` with the reason, before anything is measured; a row that raises is
    ``failed`` with its error (logged) and the others still run.  ``on_row(name)`` is
    called as each measured row starts; ``out``, when given, is filled as rows finish.
    """
    planned = plan(rows, vtk=vtk)
    out = [] if out is None else out
    pair: tuple[dict, dict] | Exception | None = None

    def cycle_pair() -> tuple[dict, dict]:
        """The two cycle rows' shared measurement, made once (a failure too: both rows
        fail with it rather than measuring for minutes again)."""
        nonlocal pair
        if pair is None:
            try:
                pair = cycle_and_timing_only(sizes, repeats)
            except Exception as exc:
                pair = exc
        if isinstance(pair, Exception):
            raise pair
        return pair

    measures: dict[str, Callable[[], dict[str, Any]]] = {
        "golden_vs_vtk_first": lambda: golden_vs_vtk_first(repeats),
        "golden_vs_vtk_rotation": lambda: golden_vs_vtk_rotation(frames),
        # VolPack frames take ~8 ms: more rounds than the other rows against the noise.
        "functional_vs_volpack": lambda: functional_vs_volpack(frames, max(repeats, 5)),
        "functional_vs_golden": lambda: functional_vs_golden(repeats),
        "cycle_samples_per_s": lambda: cycle_pair()[0],
        "timing_only_vs_cycle": lambda: cycle_pair()[1],
        "cycle_512_peak_bytes": lambda: cycle_512_peak(memory_size),
        "threads_2_vs_1": lambda: threads_2_vs_1(repeats),
    }
    out.extend(skipped(name, why) for name, why in planned if why is not None)
    for name, why in planned:
        if why is not None:
            continue
        on_row(name)
        out.append(_row(name, measures[name]))
        if out[-1]["status"] == "failed":
            log(f"{name}: failed: {out[-1]['error']}")
    out.sort(key=lambda r: ROWS.index(r["row"]))
    return out


def format_rows(rows: Sequence[dict[str, Any]]) -> str:
    """The rows as a text table: value, goal, met."""

    def show(value: float | None, unit: str) -> str:
        if value is None:
            return "-"
        if unit == "bytes":
            return f"{value / 1e9:.2f} GB"
        if unit == "samples/s":
            return f"{value / 1e6:.2f} M/s"
        return f"{value:.3g}x"

    lines = [f"{'row':<24}{'value':>11}{'goal':>11}  met"]
    for r in rows:
        sign = ">=" if r["better"] == "higher" else "<="
        met = {True: "yes", False: "no", None: status_text(r)}[r["goal_met"]]
        goal = f"{sign} {show(r['goal'], r['unit'])}"
        lines.append(f"{r['row']:<24}{show(r.get('value'), r['unit']):>11}{goal:>11}  {met}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", nargs="+", default=list(ROWS), choices=ROWS)
    parser.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    parser.add_argument("--memory-size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--no-vtk", action="store_true", help="skip the VTK rows")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    from hwsim.studies.bench import machine_info

    def say(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    for name, why in plan(args.rows, vtk=not args.no_vtk):
        if why is not None:
            say(f"{name}: skipped: {why}")
    rows = run(
        args.rows,
        vtk=not args.no_vtk,
        sizes=args.sizes,
        memory_size=args.memory_size,
        repeats=args.repeats,
        frames=args.frames,
        log=say,
        on_row=lambda name: say(f"speed table: {name}"),
    )
    print(format_rows(rows))
    report = {
        "schema": 1,
        "benchmark": "speed-table",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "rows": rows,
    }
    write_report(report, args.out)
    return 1 if any(r["status"] == "failed" for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
