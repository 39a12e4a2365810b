"""Golden-renderer speed and memory against VTK's CPU ray caster, measured in one run.

Usage::

    .venv/bin/python benchmarks/bench_golden.py [--sizes 128 256] [--out FILE.json]

For each volume size ``N`` the benchmark builds the CT-like head phantom (``N^3``), the
``ct`` transfer-function preset and a composite, one-light Phong scene, then

* times ``hwsim.golden.render_golden`` (median of ``--golden-repeats`` renders) and
  ``vtkFixedPointVolumeRayCastMapper`` (one warm-up frame, median of ``--vtk-frames``)
  in this process, on the same volume, transfer function, camera, light, material,
  sample distance and image size;
* measures each renderer's peak memory in its own subprocess (``--worker``), so the two
  do not contaminate each other: the high-water mark (``VmHWM``) is reset after the
  volume is built, so ``render_rss_bytes`` is what rendering adds to the resident set;
* writes a JSON report (``--out``) and prints a table.

``ratio`` is the golden renderer's speed relative to VTK's, as a frame-time ratio
(``vtk_seconds / golden_seconds``); the goal is :data:`GOAL_RATIO`.  Benchmarks are not
tests (docs/conventions.md item 11): nothing here asserts a speed.
"""

from __future__ import annotations

import argparse
import gc
import json
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):  # run as a script: make `benchmarks` and `hwsim` importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report
from hwsim.spec.scene import Light, Material, RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec
from hwsim.spec.transfer import TransferFunction, resolve_transfer
from hwsim.volumes import Volume, make_phantom

__all__ = [
    "GOAL_RATIO",
    "SCHEMA",
    "build_case",
    "format_table",
    "machine_info",
    "main",
    "measure_memory",
    "psnr",
    "run_benchmark",
]

SCHEMA = 1
#: The golden renderer should run at least this fraction of VTK's speed.
GOAL_RATIO = 0.5
AZIMUTH, ELEVATION = 30.0, 15.0  # the built-in `head` scene's view
SCRIPT = Path(__file__).resolve()


# --------------------------------------------------------------------------- the scene


def load_head(size: int) -> tuple[Volume, str]:
    """The CT-like head phantom at ``size^3`` and where it came from."""
    return make_phantom("head", size=size), "hwsim.volumes.make_phantom"


def make_scene(size: int, width: int, height: int, early_termination: float) -> Scene:
    """The benchmark scene: head phantom, ``ct`` preset, composite, one-light Phong."""
    return Scene(
        name=f"bench-head-{size}",
        source="<benchmarks>",
        volume=VolumeSpec(phantom="head", params=(("size", size),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=AZIMUTH, elevation=ELEVATION, width=width, height=height),
        lights=(Light(direction=(-0.4, 0.5, 1.0)),),
        material=Material(ambient=0.15, diffuse=0.7, specular=0.3, shininess=24.0),
        render=RenderSpec(mode="composite", lighting=True, early_termination=early_termination),
    )


def build_case(
    size: int, width: int, height: int, early_termination: float
) -> tuple[Volume, TransferFunction, Scene, str]:
    """Volume, transfer function, scene and volume provenance for one benchmark case."""
    volume, origin = load_head(size)
    scene = make_scene(size, width, height, early_termination)
    transfer = resolve_transfer(scene.transfer, volume)
    return volume, transfer, scene, origin


def _tf_points(transfer: TransferFunction) -> list[tuple[float, float, float, float, float]]:
    return [
        (float(v), *(float(c) for c in rgba))  # type: ignore[misc]
        for v, rgba in zip(transfer.values, transfer.rgba, strict=True)
    ]


def _vtk_kwargs(volume: Volume, transfer: TransferFunction, scene: Scene) -> dict[str, Any]:
    """Arguments of :func:`benchmarks.vtk_reference.render_vtk` for ``scene``."""
    light, mat = scene.lights[0], scene.material
    return dict(
        data_zyx=volume.data,
        spacing_zyx=volume.spacing,
        tf_points=_tf_points(transfer),
        width=scene.view.width,
        height=scene.view.height,
        azimuth=scene.view.azimuth,
        elevation=scene.view.elevation,
        shading=scene.lit,
        material=(mat.ambient, mat.diffuse, mat.specular, mat.shininess),
        sample_distance=scene.render.step * min(volume.spacing),
        light_direction=light.direction,
        light_intensity=light.intensity,
        zoom=scene.view.zoom,
    )


def _golden() -> Callable[..., Any] | None:
    try:
        from hwsim.golden import render_golden  # type: ignore[attr-defined]
    except ImportError:
        return None
    return render_golden


# --------------------------------------------------------------------------- measuring


def machine_info() -> dict[str, Any]:
    """CPU model, cores, Python/NumPy/VTK versions and how VTK renders here."""
    from benchmarks.vtk_reference import vtk_environment
    from hwsim.studies.bench import machine_info as host

    env = vtk_environment()
    return {
        **host(),
        "vtk": env["vtk_version"],
        "vtk_window_class": env["window_class"],
        "vtk_opengl_renderer": env["opengl_renderer"],
        "vtk_threads": env["threads"],
    }


def psnr(reference: np.ndarray, test: np.ndarray) -> float:
    """PSNR in dB of ``test`` against ``reference``, colour channels clipped to [0, 1].

    The metric is :func:`hwsim.numerics.metrics.psnr` (peak 1.0).
    """
    from hwsim.numerics.metrics import psnr as psnr_db

    a = np.clip(np.asarray(reference, dtype=np.float64)[..., :3], 0.0, 1.0)
    b = np.clip(np.asarray(test, dtype=np.float64)[..., :3], 0.0, 1.0)
    return psnr_db(a, b)


def _time_golden(
    render_golden: Callable[..., Any],
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    repeats: int,
) -> tuple[dict[str, Any], np.ndarray]:
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = render_golden(scene, volume, transfer)
        times.append(time.perf_counter() - start)
    assert result is not None
    seconds = statistics.median(times)
    samples = int(result.samples)
    out = {
        "samples": samples,
        "rays": int(getattr(result, "rays", 0)),
        "seconds": seconds,
        "seconds_all": times,
        "samples_per_second": samples / seconds,
        "frames_per_second": 1.0 / seconds,
    }
    return out, np.asarray(result.image)


def _time_vtk(
    volume: Volume, transfer: TransferFunction, scene: Scene, frames: int
) -> tuple[dict[str, Any], np.ndarray]:
    from benchmarks.vtk_reference import VTK_EARLY_TERMINATION, render_vtk

    stats: dict[str, Any] = {}
    image, seconds = render_vtk(**_vtk_kwargs(volume, transfer, scene), frames=frames, stats=stats)
    out = {
        "seconds": seconds,
        "frames_per_second": 1.0 / seconds,
        "first_frame_seconds": stats["first_frame_seconds"],
        "seconds_all": stats["frame_seconds"],
        "threads": stats["threads"],
        "sample_distance": stats["sample_distance"],
        "early_termination": VTK_EARLY_TERMINATION,
        "window_class": stats["window_class"],
    }
    if stats["threads"] != 1:  # the golden renderer is one NumPy thread: show that too
        _, one = render_vtk(**_vtk_kwargs(volume, transfer, scene), frames=frames, threads=1)
        out["seconds_one_thread"] = one
    else:
        out["seconds_one_thread"] = seconds
    return out, image


def _status_kib(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise RuntimeError(f"{field} not in /proc/self/status")


def _worker(
    renderer: str, size: int, width: int, height: int, early_termination: float
) -> dict[str, Any]:
    """Render once in this (fresh) process and report its memory high-water marks."""
    import resource

    volume, transfer, scene, _ = build_case(size, width, height, early_termination)
    if renderer == "golden":
        render_golden = _golden()
        if render_golden is None:
            raise RuntimeError("hwsim.golden.render_golden is not available")

        def run() -> None:
            render_golden(scene, volume, transfer)
    else:
        from benchmarks.vtk_reference import VtkRayCaster

        def run() -> None:
            caster = VtkRayCaster(**_vtk_kwargs(volume, transfer, scene))
            caster.render()  # warm-up: computes and encodes the gradients
            caster.render()
            caster.image()
            caster.close()

    gc.collect()
    Path("/proc/self/clear_refs").write_text("5")  # reset VmHWM to the current RSS
    baseline = _status_kib("VmRSS") * 1024
    run()
    peak = _status_kib("VmHWM") * 1024
    return {
        "peak_rss_bytes": peak,
        "baseline_rss_bytes": baseline,
        "render_rss_bytes": peak - baseline,
        "process_max_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
    }


def measure_memory(
    renderer: str, size: int, width: int, height: int, early_termination: float
) -> dict[str, Any]:
    """Peak memory of one ``renderer`` (``golden`` or ``vtk``) render, in a subprocess.

    Returns ``peak_rss_bytes`` (high-water mark of the resident set from just before
    the render, volume already built), ``baseline_rss_bytes`` (resident set then),
    ``render_rss_bytes`` (their difference: what rendering adds) and
    ``process_max_rss_bytes`` (the subprocess's lifetime peak, including building the
    volume).
    """
    cmd = [
        sys.executable,
        str(SCRIPT),
        "--worker",
        renderer,
        "--sizes",
        str(size),
        "--width",
        str(width),
        "--height",
        str(height),
        "--early-termination",
        repr(early_termination),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        tail = done.stderr.strip().splitlines()[-1:] or ["(no output)"]
        raise RuntimeError(f"{renderer} memory worker failed: {tail[0]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def run_benchmark(
    sizes: Sequence[int] = (128, 256),
    images: Sequence[int | str] = (256, "matched"),
    *,
    golden_repeats: int = 3,
    vtk_frames: int = 10,
    early_termination: float | None = None,
    memory: bool = True,
    log: Callable[[str], None] = _log,
) -> dict[str, Any]:
    """Measure every (volume size, image size) case; return the JSON-ready report.

    Parameters
    ----------
    sizes : sequence of int
        Volume sides ``N`` (``N^3`` voxels).
    images : sequence of int or "matched"
        Square image sides; ``"matched"`` means ``N``.  Duplicates are measured once.
    golden_repeats, vtk_frames : int
        Timed golden renders and timed VTK frames (after one warm-up) per case.
    early_termination : float, optional
        Golden early-ray-termination opacity; default VTK's built-in threshold
        (:data:`benchmarks.vtk_reference.VTK_EARLY_TERMINATION`), so both renderers
        stop rays at the same accumulated opacity.
    memory : bool
        Measure peak memory in subprocesses.
    log : callable
        Receives one progress line per step.
    """
    from benchmarks.vtk_reference import VTK_EARLY_TERMINATION

    if early_termination is None:
        early_termination = VTK_EARLY_TERMINATION
    render_golden = _golden()
    report: dict[str, Any] = {
        "schema": SCHEMA,
        "benchmark": "golden-vs-vtk-fixed-point-ray-cast",
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine_info(),
        "goal_ratio": GOAL_RATIO,
        "golden_available": render_golden is not None,
        "cases": [],
    }
    for size in sizes:
        sides = list(dict.fromkeys(size if s == "matched" else int(s) for s in images))
        for side in sides:
            label = f"{size}^3 -> {side}x{side}"
            volume, transfer, scene, origin = build_case(size, side, side, early_termination)
            image_bytes = side * side * 4 * 8
            case: dict[str, Any] = {
                "size": size,
                "image": [side, side],
                "volume": {
                    "source": origin,
                    "shape": list(volume.shape),
                    "dtype": str(volume.data.dtype),
                    "spacing": list(volume.spacing),
                    "bytes": volume.nbytes,
                },
                "image_bytes_float64_rgba": image_bytes,
                "scene": {
                    "mode": scene.render.mode,
                    "lighting": scene.lit,
                    "azimuth": scene.view.azimuth,
                    "elevation": scene.view.elevation,
                    "sample_distance": scene.render.step * min(volume.spacing),
                    "early_termination": early_termination,
                    "transfer": "ct preset",
                    "light_direction_view": list(scene.lights[0].direction),
                    "material": [
                        scene.material.ambient,
                        scene.material.diffuse,
                        scene.material.specular,
                        scene.material.shininess,
                    ],
                },
            }
            log(f"[{label}] vtk: timing {vtk_frames} frames")
            vtk_stats, vtk_image = _time_vtk(volume, transfer, scene, vtk_frames)
            golden_stats: dict[str, Any] | None = None
            golden_image = None
            if render_golden is not None:
                log(f"[{label}] golden: timing {golden_repeats} render(s)")
                golden_stats, golden_image = _time_golden(
                    render_golden, scene, volume, transfer, golden_repeats
                )
            del volume, transfer
            gc.collect()
            if memory:
                log(f"[{label}] vtk: peak memory (subprocess)")
                vtk_stats.update(measure_memory("vtk", size, side, side, early_termination))
                if golden_stats is not None:
                    log(f"[{label}] golden: peak memory (subprocess)")
                    golden_stats.update(
                        measure_memory("golden", size, side, side, early_termination)
                    )
                    vol_bytes = case["volume"]["bytes"]
                    golden_stats["peak_rss_over_volume_bytes"] = (
                        golden_stats["peak_rss_bytes"] / vol_bytes
                    )
                    golden_stats["render_rss_over_volume_plus_image_bytes"] = golden_stats[
                        "render_rss_bytes"
                    ] / (vol_bytes + image_bytes)
            case["vtk"] = vtk_stats
            case["golden"] = golden_stats
            if golden_stats is not None:
                ratio = vtk_stats["seconds"] / golden_stats["seconds"]
                case["ratio"] = ratio
                case["ratio_vs_vtk_one_thread"] = (
                    vtk_stats["seconds_one_thread"] / golden_stats["seconds"]
                )
                case["goal_met"] = ratio >= GOAL_RATIO
                same_shape = golden_image is not None and golden_image.shape == vtk_image.shape
                agreement = psnr(golden_image, vtk_image) if same_shape else None
                case["psnr_golden_vs_vtk_db"] = (
                    agreement if agreement is not None and np.isfinite(agreement) else None
                )
                log(
                    f"[{label}] golden {golden_stats['seconds']:.3f} s, "
                    f"vtk {vtk_stats['seconds']:.4f} s, ratio {ratio:.3g}"
                )
            else:
                case["ratio"] = None
                case["ratio_vs_vtk_one_thread"] = None
                case["goal_met"] = None
                case["psnr_golden_vs_vtk_db"] = None
                log(f"[{label}] vtk {vtk_stats['seconds']:.4f} s; golden renderer not available")
            report["cases"].append(case)
    return report


# --------------------------------------------------------------------------- output


def _mib(n: float | None) -> str:
    return "-" if n is None else f"{n / 2**20:.0f}"


def format_table(report: dict[str, Any]) -> str:
    """The report as a fixed-width text table."""
    m = report["machine"]
    lines = [
        f"{m['cpu_model']}, {m['usable_cores']} cores; Python {m['python']}, "
        f"NumPy {m['numpy']}, VTK {m['vtk']} ({m['vtk_window_class']}, "
        f"{m['vtk_threads']} threads)",
        "",
        f"{'case':<18}{'golden s':>10}{'Msamples/s':>11}{'gold MiB':>9}{'+render':>8}"
        f"{'vtk s':>9}{'vtk1 s':>9}{'vtk fps':>8}{'vtk MiB':>8}{'ratio':>8}{'goal':>6}{'PSNR':>7}",
    ]
    for case in report["cases"]:
        g, v = case["golden"] or {}, case["vtk"]
        label = f"{case['size']}^3 {case['image'][0]}x{case['image'][1]}"
        ratio = case["ratio"]
        goal = "-" if case["goal_met"] is None else ("yes" if case["goal_met"] else "no")
        psnr_db = case["psnr_golden_vs_vtk_db"]
        lines.append(
            f"{label:<18}"
            f"{g.get('seconds', float('nan')):>10.3f}"
            f"{g.get('samples_per_second', float('nan')) / 1e6:>11.2f}"
            f"{_mib(g.get('peak_rss_bytes')):>9}{_mib(g.get('render_rss_bytes')):>8}"
            f"{v['seconds']:>9.4f}{v['seconds_one_thread']:>9.4f}{v['frames_per_second']:>8.1f}"
            f"{_mib(v.get('peak_rss_bytes')):>8}"
            f"{'-' if ratio is None else f'{ratio:.3g}':>8}{goal:>6}"
            f"{'-' if psnr_db is None else f'{psnr_db:.1f}':>7}"
        )
    lines.append("")
    lines.append(
        f"ratio = vtk seconds / golden seconds (goal >= {report['goal_ratio']}); "
        "vtk1 = VTK on one thread; MiB = peak RSS, +render = what rendering adds"
    )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; see the module docstring."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sizes",
        type=int,
        nargs="+",
        default=[128, 256],
        help="volume sides N (N^3 voxels); default 128 256",
    )
    parser.add_argument(
        "--images",
        nargs="+",
        default=["256", "matched"],
        help="square image sides, or 'matched' (= N); default 256 matched",
    )
    parser.add_argument("--golden-repeats", type=int, default=3)
    parser.add_argument("--vtk-frames", type=int, default=10)
    parser.add_argument(
        "--early-termination",
        type=float,
        default=None,
        help="golden ERT opacity; default VTK's built-in 0.9922",
    )
    parser.add_argument(
        "--no-memory", action="store_true", help="skip the peak-memory subprocesses"
    )
    parser.add_argument("--out", type=Path, default=None, help="write the JSON report here")
    parser.add_argument("--worker", choices=("golden", "vtk"), help=argparse.SUPPRESS)
    parser.add_argument("--width", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--height", type=int, help=argparse.SUPPRESS)
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    try:
        if args.worker:
            et = args.early_termination
            if et is None:
                from benchmarks.vtk_reference import VTK_EARLY_TERMINATION as et
            print(json.dumps(_worker(args.worker, args.sizes[0], args.width, args.height, et)))
            return 0
        images: list[int | str] = []
        for item in args.images:
            images.append("matched" if item == "matched" else int(item))
        report = run_benchmark(
            args.sizes,
            images,
            golden_repeats=args.golden_repeats,
            vtk_frames=args.vtk_frames,
            early_termination=args.early_termination,
            memory=not args.no_memory,
        )
        report["command"] = " ".join(["python", "benchmarks/bench_golden.py", *argv])
    except Exception as exc:  # one line on stderr, non-zero exit (conventions item 8)
        print(f"bench_golden: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    print(format_table(report))
    write_report(report, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
