"""One frame split across Dask workers: ``hwsim render --workers N`` / ``--scheduler ADDR``.

# Ref: issue 20 (Cube-4's 1024^3 frame, simulated); shared/docs/design.md section 8
#      (distributed work on Dask, as sweeps run).

The machine family cuts the frame's rays into bands (``Machine.split``: for the Cube-4
family :class:`models.machines.cube4.bands.BandSplit`); each band is one Dask task that
rebuilds the frame from the scene, architecture, transfer function and the volume's
:class:`~hwsim.volumes.parts.VolumeParts` (a description: the voxels are read or
generated on the worker, a box at a time), runs its rays and returns their accumulators,
per-step pipeline loads and counts.  The driver combines them by the machine's rules into
one frame, bit-identical to a one-process render.

Progress: every band reports its steps through a Dask queue and the driver shows one bar
for the frame.  A worker that dies holding a band is replaced and the band rerun
(:data:`hwsim.core.cluster.ALLOWED_FAILURES`); the frame still completes, bit-identical.
"""

from __future__ import annotations

import time
import uuid
from collections.abc import Callable
from dataclasses import asdict
from typing import Any

from hwsim.core import env
from hwsim.core.errors import InputError

__all__ = ["split_frame", "PROGRESS_EVERY"]

#: A band reports its progress every this many steps (and at its last).
PROGRESS_EVERY = 8


def _band_task(scene, arch, transfer, volume, rays, band, faults, queue_name):
    """One band on a worker: the frame rebuilt from its description, the band's rays run."""
    from distributed import Queue

    from models.frame import frame_of
    from models.machines import machine_for

    frame = frame_of(scene, volume, transfer, arch)
    queue = Queue(queue_name) if queue_name else None

    def progress(done: int, total: int) -> None:
        if queue is not None and (done % PROGRESS_EVERY == 0 or done == total):
            queue.put((band, done, total))

    split = machine_for(arch, "cycle").split
    return split.task(frame, volume.meta["parts"], rays, band, faults=faults, progress=progress)


def split_frame(
    frame,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    bands: int | None = None,
    faults: object | None = None,
    progress: Callable[[int, int], None] | None = None,
    client: Any = None,
    trace: bool = False,
) -> tuple[Any, dict]:
    """Render ``frame`` (its volume read in parts: :meth:`VolumeParts.volume`) at cycle
    fidelity on Dask: ``bands`` bands (default: one per worker) on a local cluster of
    ``workers`` processes, the cluster at ``scheduler``, or ``client``'s.

    Returns the frame's :class:`~models.machines.common.results.CycleResult` and what
    the split did (``workers``, ``bands``: each band's rays, samples, beams read, seconds,
    peak memory and host, ``driver_peak_rss_bytes``).
    """
    from hwsim.core.cluster import client_for
    from models.machines import machine_for

    family = machine_for(frame.arch, "cycle")
    if family.split is None:
        raise InputError(
            f"{frame.arch.name} renders a frame in one process",
            key="--workers",
            allowed="a machine of the Cube-4 family (cube4, cube4-teramac)",
        )
    if "parts" not in frame.volume.meta:
        raise InputError(
            "a frame split across workers reads its volume in parts",
            key="--workers",
            allowed="the head phantom or a volume file",
        )
    split = family.split(frame, faults, trace=trace)
    start = time.perf_counter()
    if client is None:
        with client_for(workers, scheduler) as own:
            return _run(split, frame, own, bands, faults, progress, start)
    return _run(split, frame, client, bands, faults, progress, start)


def _run(split, frame, client, bands, faults, progress, start) -> tuple[Any, dict]:
    from distributed import Queue, as_completed

    from hwsim.core.cluster import heartbeat, peak_rss_bytes, scheduler_timeout, scheduler_workers

    n_workers = max(1, len(scheduler_workers(client)))  # bounded: a silent scheduler fails
    alive, seconds = heartbeat(client), scheduler_timeout()
    groups = split.bands(int(bands or n_workers))
    token = uuid.uuid4().hex[:12]
    queue = Queue(f"hwsim-progress-{token}", client=client)
    task = env.Carried(_band_task, env.settings(HWSIM_THREADS="1"))  # the client's values
    futures = [
        client.submit(
            task,
            frame.scene,
            frame.arch,
            frame.transfer,
            frame.volume,
            rays,
            band,
            faults,
            queue.name,
            key=f"hwsim-band-{token}-{band}",
            pure=False,
        )
        for band, rays in enumerate(groups)
    ]
    steps = frame.plan.n_steps
    done = dict.fromkeys(range(len(groups)), 0)
    shown = 0
    total = steps * len(groups)
    if progress is not None:
        progress(0, total)
    results: dict[int, Any] = {}
    pending = as_completed(futures, with_results=False)
    by_key = {f.key: band for band, f in enumerate(futures)}
    remaining = set(range(len(groups)))
    while remaining:
        alive()  # every few seconds: does the scheduler still answer?
        for band, step, _ in _drain(queue, seconds):
            done[band] = max(done[band], step)  # a rerun band starts again from 0
        if progress is not None and sum(done.values()) > shown:
            shown = sum(done.values())
            progress(min(shown, total), total)
        finished = pending.next_batch(block=False) if pending.has_ready() else []
        for future in finished:
            band = by_key[future.key]
            try:
                results[band] = future.result(timeout=seconds)
            except TimeoutError:  # finished, but its result never came
                raise InputError(
                    f"band {band}'s result did not arrive within {seconds:g} s", key="--scheduler"
                ) from None
            remaining.discard(band)
            done[band] = steps
        if remaining and not finished:
            time.sleep(0.05)
    if progress is not None:
        progress(total, total)
    sweeps = [results[b][0] for b in range(len(groups))]
    reports = [asdict(results[b][1]) for b in range(len(groups))]
    result = split.combine(sweeps)
    info = {
        "workers": n_workers,
        "bands": reports,
        "seconds": time.perf_counter() - start,
        "driver_peak_rss_bytes": peak_rss_bytes(),
        "peak_rss_bytes": max([r["peak_rss_bytes"] for r in reports] + [peak_rss_bytes()]),
    }
    return result, info


def _drain(queue, seconds: float) -> list[tuple[int, int, int]]:
    """Every progress message waiting in ``queue`` (none: an empty list, at once), each
    exchange with the scheduler bounded by ``seconds`` (a silent one: one-line error)."""
    try:
        waiting = queue.qsize(callback_timeout=seconds)
        return queue.get(batch=waiting, callback_timeout=seconds) if waiting else []
    except TimeoutError:
        raise InputError(
            f"the scheduler stopped answering (no reply within {seconds:g} s)", key="--scheduler"
        ) from None
