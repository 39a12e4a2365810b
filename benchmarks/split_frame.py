"""One Cube-4 cycle frame split across Dask workers: the scaling table and its checks.

Usage::

    .venv/bin/python benchmarks/split_frame.py [--sizes 256 512 1024] [--workers 1 2]
        [--volume head|ct] [--pipelines P] [--reference-max 256]
        [--out benchmarks/results/split-frame.json]

Each (size, workers) starts a local Dask cluster of that many single-thread worker
processes (``hwsim.core.cluster.local_client``, as ``hwsim render --workers`` does) and renders
the dense scenario (``hwsim.studies.figures.figure_scene``: the head scene's transfer function,
light and material on an ``N^3`` volume viewed along an axis, one sample per voxel) at
cycle fidelity through ``--scheduler`` on that cluster, twice: the first frame pays the
workers' imports and kernel loads (``cold``), the second is what every later frame on a
running cluster costs (``warm``).  Reported per frame: wall seconds, samples per second,
the peak resident memory of every band's worker and of this driver process.

Checks, in the same run: the frames with 1 and 2 workers have the same image, cycles and
counters bit for bit; up to ``--reference-max`` the one-process render too (above it a
one-process frame needs the whole volume in memory: 2.26 GB at 512^3, ~18 GB at 1024^3).
The two halves of that check are not alike (``CHECK_INDEPENDENCE``, written beside each
check): the image is computed per band from the band's own rows, halo, skewed stream and
routing, so its equality is evidence; the cycles and the timing counters are computed
once by ``Cube4Machine.frame`` in the driver from the whole plan, so theirs holds by
construction (docs/distributed-frames.md, "What the equality shows").

``--volume ct`` renders the CT of ``../shared/data/ct_cranium.nrrd`` resampled
(trilinear) to ``N^3`` and written to a scratch ``.npy`` a slab at a time, read by the
workers a box at a time; ``head`` generates the phantom's parts on the workers.
``--pipelines`` renders a what-if Cube-4 with that many pipelines (the 1024^3 claim's P
was not published: architectures.md 1.4).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.report_io import write_report

CT = Path(__file__).resolve().parents[2] / "shared" / "data" / "ct_cranium.nrrd"

#: What each half of a check's equality shows (docs/distributed-frames.md).
CHECK_INDEPENDENCE = {
    "image": "evidence: each band computes its halo (_band_origins), reads its rows, builds "
    "its skewed stream (band_stream) and routes it through a band-sized datapath; shared "
    "with the one-process frame: the plan, sample_pass, SliceDatapath, corner_planes and "
    "the back end's arithmetic",
    "cycles_and_counters": "by construction: Cube4Machine.frame times the whole frame from "
    "the whole plan in the driver (slice reads, cube4_pixel_pushes, freezing_fifo, "
    "cube4_latency); the bands add only per-step busy sums over disjoint rays",
}


def _digest(result) -> dict[str, str]:
    """SHA-256 of the image and of the counters (cycles included) of one frame."""
    counters = json.dumps(result.counters, sort_keys=True, default=str).encode()
    return {
        "image_sha256": hashlib.sha256(np.ascontiguousarray(result.image).tobytes()).hexdigest(),
        "counters_sha256": hashlib.sha256(counters).hexdigest(),
    }


def resample_ct(n: int, folder: Path) -> Path:
    """The CT resampled trilinearly to ``n^3`` (int16 HU), written slab by slab."""
    from hwsim.volumes import read_volume

    ct = read_volume(CT).data.astype(np.float32)
    path = folder / f"ct-{n}.npy"
    out = np.lib.format.open_memmap(path, mode="w+", dtype=np.int16, shape=(n, n, n))

    def taps(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = np.linspace(0.0, m - 1.0, n)
        i0 = np.minimum(np.floor(x).astype(np.int64), m - 2)
        return i0, i0 + 1, (x - i0).astype(np.float32)

    (z0, z1, wz), (y0, y1, wy), (x0, x1, wx) = (taps(m) for m in ct.shape)
    for k in range(n):
        plane = (1 - wz[k]) * ct[z0[k]] + wz[k] * ct[z1[k]]
        rows = (1 - wy)[:, None] * plane[y0] + wy[:, None] * plane[y1]
        out[k] = np.rint((1 - wx) * rows[:, x0] + wx * rows[:, x1])
    out.flush()
    del out
    return path


def scene_for(n: int, volume: str, scratch: Path):
    from hwsim.spec.scene import VolumeSpec
    from hwsim.studies.figures import figure_scene

    scene = figure_scene(n)
    if volume == "ct":
        scene = scene.replace(volume=VolumeSpec(path=str(resample_ct(n, scratch))))
    return scene


def frame(scene, arch, scheduler: str | None) -> tuple[Any, float, int]:
    from hwsim.core.cluster import peak_rss_bytes, reset_peak_rss
    from hwsim.run.fidelity import render

    reset_peak_rss()
    start = time.perf_counter()
    run = render(scene, fidelity="cycle", arch=arch, scheduler=scheduler)
    return run, time.perf_counter() - start, peak_rss_bytes()


def run(
    sizes=(256, 512, 1024),
    workers=(1, 2),
    *,
    volume: str = "head",
    pipelines: int | None = None,
    reference_max: int = 256,
    warm_max: int = 512,
    scratch: str | None = None,
    log=lambda line: print(line, file=sys.stderr, flush=True),
) -> dict[str, Any]:
    """The scaling table (see the module docstring) as a JSON-ready report."""
    from hwsim.core.cluster import local_client
    from hwsim.run.fidelity import resolve_arch

    arch = resolve_arch("cube4")
    if pipelines:
        arch = dataclasses.replace(arch, pipelines=pipelines)
    rows, checks = [], []
    with tempfile.TemporaryDirectory(dir=scratch) as folder:
        for n in sizes:
            scene = scene_for(n, volume, Path(folder))
            digests = {}
            if n <= reference_max:
                result, wall, peak = frame(scene, arch, None)
                digests["one process"] = (_digest(result), result.cycles)
                rows.append(_row(n, "one process", None, result, wall, peak))
                log(_line(rows[-1]))
            for w in workers:
                with local_client(w) as client:
                    address = client.scheduler.address
                    for phase in ("cold", "warm")[: 2 if n <= warm_max else 1]:
                        result, wall, peak = frame(scene, arch, address)
                        rows.append(_row(n, phase, w, result, wall, peak))
                        log(_line(rows[-1]))
                digests[f"{w} workers"] = (_digest(result), result.cycles)
            first = next(iter(digests.values()))
            image = all(d[0]["image_sha256"] == first[0]["image_sha256"] for d in digests.values())
            timing = all(
                (d[0]["counters_sha256"], d[1]) == (first[0]["counters_sha256"], first[1])
                for d in digests.values()
            )
            checks.append(
                {
                    "size": n,
                    "compared": list(digests),
                    "identical": all(d == first for d in digests.values()),
                    "image_identical": image,
                    "cycles_and_counters_identical": timing,
                    "independence": CHECK_INDEPENDENCE,
                    "cycles": first[1],
                }
            )
            log(f"{n}^3 identical: {checks[-1]['identical']}")
    speedups = {}
    for n in sizes:
        by = {(r["phase"], r["workers"]): r["seconds"] for r in rows if r["size"] == n}
        for phase in ("cold", "warm"):
            if (phase, 1) in by and (phase, 2) in by:
                speedups[f"{n}^3 {phase}"] = by[(phase, 1)] / by[(phase, 2)]
    return {
        "schema": 1,
        "benchmark": "split-frame",
        "scene": f"dense scenario (hwsim.studies.figures.figure_scene), volume {volume}",
        "machine": {"arch": arch.name, "pipelines": arch.pipelines, "clock_hz": arch.clock_hz},
        "rows": rows,
        "checks": checks,
        "speedup_2_vs_1": speedups,
        "host": _host(),
    }


def _row(n, phase, workers, run, wall, driver_peak) -> dict[str, Any]:
    split = run.split or {}
    bands = split.get("bands", [])
    return {
        "size": n,
        "phase": phase,
        "workers": workers,
        "seconds": wall,
        "samples": run.samples,
        "samples_per_second": run.samples / wall,
        "cycles": run.cycles,
        "simulated_fps": run.clock_hz / run.cycles,
        "driver_peak_rss_bytes": driver_peak,
        "worker_peak_rss_bytes": [b["peak_rss_bytes"] for b in bands],
        "band_seconds": [b["seconds"] for b in bands],
        "band_rows_read": [b["rows"] for b in bands],
    }


def _line(row) -> str:
    peaks = ", ".join(f"{p / 2**30:.2f}" for p in row["worker_peak_rss_bytes"]) or "-"
    who = "one process" if row["workers"] is None else f"{row['workers']} workers {row['phase']}"
    return (
        f"{row['size']}^3 {who:<18} {row['seconds']:8.2f} s  "
        f"{row['samples_per_second'] / 1e6:7.2f} M samples/s  driver "
        f"{row['driver_peak_rss_bytes'] / 2**30:.2f} GB  workers [{peaks}] GB  "
        f"{row['cycles']:,} cycles"
    )


def _host() -> dict[str, Any]:
    import os
    import platform

    return {
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--volume", choices=("head", "ct"), default="head")
    p.add_argument("--pipelines", type=int, default=None)
    p.add_argument("--reference-max", type=int, default=256)
    p.add_argument("--warm-max", type=int, default=512, help="largest size timed twice")
    p.add_argument("--scratch", default=None, help="folder for the resampled CT")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    report = run(
        args.sizes,
        args.workers,
        volume=args.volume,
        pipelines=args.pipelines,
        reference_max=args.reference_max,
        warm_max=args.warm_max,
        scratch=args.scratch,
    )
    write_report(report, args.out)
    return 0 if all(c["identical"] for c in report["checks"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
