"""Supervolumes: a volume over a machine's one-pass limit, rendered brick by brick and
blended on the host, as VolumePro 500's software did.

# Ref: architectures.md section 3 ([V] FAQ: "up to 256 voxels in every dimension; larger
#      'supervolumes' split in software"; [V] half-length PCI board); the split and the
#      blend are [I] (hwsim/golden/bricks.py; the host blend below).

Each brick (:func:`hwsim.golden.bricks.split_bricks`) is one frame of the machine: its
voxels, the samples of the whole plan it owns (:class:`~hwsim.golden.bricks.BrickPlan`),
the whole volume's transfer function and value range, rendered at the asked rung.  The
machine leaves each brick's base plane (the image, for shear-image) in its output format
(unorm ``output_bits``: RGBA8 on VolumePro 500); the host reads every brick's pixels back
over the board's bus and blends them, per pixel, front to back in the order its ray meets
the bricks (by the first step it takes in each), in the same unorm arithmetic::

    C += round((F - A) c / F),  A += round((F - A) a / F)   (F = 2**bits - 1, nearest-up)

then warps the blended base plane once.  MIP and MinIP keep the largest or smallest
value.  A pixel only one brick touches is that brick's pixel exactly, so a volume of one
brick renders bit for bit as in one pass.

Timing: the frame is the bricks' frames back to back (their cycles summed) plus the read
back of their pixels over ``[overheads] host_bus_bytes_per_second`` (4 bytes per pixel;
the host's blend arithmetic is not timed) [I].  This module states only the host's part
(``derived.supervolume.host_seconds``, :func:`host_seconds`); the frame's seconds and
rate, the machine's alone and with the host's read back, are computed once from it by
:func:`hwsim.run.output.frame_timing` for ``stats.json`` and the render summary.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.engine.metrics import derive
from hwsim.golden.bricks import HALO, BrickPlan, split_bricks
from hwsim.golden.positions import make_plan
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import Scene
from hwsim.spec.transfer import TransferFunction
from hwsim.volumes.volume import Volume

__all__ = [
    "SupervolumeResult",
    "blend_unorm",
    "host_seconds",
    "oversize",
    "refuse_supervolume",
    "render_bricks",
]

#: Modes the host blend models.
MODES = ("composite", "mip", "minip")
#: Bytes of one base-plane pixel read back (RGBA8) [I].
PIXEL_BYTES = 4


def oversize(volume: Volume, arch: ArchConfig) -> bool:
    """Whether ``volume`` exceeds what ``arch`` renders in one pass."""
    return any(n > m for n, m in zip(volume.shape, arch.max_volume, strict=True))


def refuse_supervolume(scene: Scene, arch: ArchConfig, fidelity: str, **options: Any) -> None:
    """Refuse a supervolume render the bricks cannot model (one line, naming the key)."""

    def refuse(message: str, key: str, allowed: str) -> InputError:
        return InputError(
            f"{arch.name} renders this volume in bricks (supervolume): {message}",
            source=arch.source,
            key=key,
            allowed=allowed,
        )

    if fidelity not in ("functional", "transaction", "cycle"):
        raise refuse(
            "the rtl top holds one small volume",
            "--fidelity",
            "golden, functional, transaction, cycle",
        )
    if arch.order == "ray":
        raise refuse(
            "bricks are modelled for slice-order machines", "pipeline.order", "a slice order"
        )
    if scene.render.mode not in MODES:
        raise refuse(f"the host blend has no {scene.render.mode}", "render.mode", ", ".join(MODES))
    if arch.space_leaping:
        raise refuse("a brick does not leap", "features.space_leaping", "false")
    if scene.geometry is not None:
        raise refuse("embedded geometry is per frame, not per brick", "geometry", "no [geometry]")
    for option, key in (
        ("trace", "--trace"),
        ("steady_state", "steady_state"),
        ("elaborate_all", "elaborate_all"),
    ):
        if options.get(option):
            raise refuse("one frame per brick", key, "off")


@dataclass
class SupervolumeResult:
    """A supervolume frame, shaped as the rungs' results are."""

    image: np.ndarray
    samples: int
    rays: int
    cycles: int
    counters: dict[str, Any]
    derived: dict[str, Any] = field(default_factory=dict)
    elaborated_units: list[str] = field(default_factory=list)
    elided_units: list[str] = field(default_factory=list)


def blend_unorm(acc: np.ndarray, rgba: np.ndarray, bits: int) -> None:
    """The host's front-to-back blend of unorm ``rgba`` ``(n, 4)`` behind ``acc`` (in
    place, rows pairwise): ``x += round((F - A) x' / F)``, clamped to ``F``."""
    full = (1 << bits) - 1
    weight = full - acc[:, 3:4]
    acc += (2 * weight * rgba + full) // (2 * full)
    np.minimum(acc, full, out=acc)


def render_bricks(
    scene: Scene,
    volume: Volume,
    transfer: TransferFunction,
    arch: ArchConfig,
    render_frame: Callable[[Any], Any],
    frame_of: Callable[..., Any],
    progress: Callable[[int, int], None] | None = None,
) -> SupervolumeResult:
    """Render ``volume`` on ``arch`` in bricks, each through ``render_frame(frame)`` (a
    rung), ``frame_of(scene, brick_volume, transfer, arch, plan)`` building its frame."""
    whole = make_plan(scene, volume, arch.order)
    bricks = split_bricks(volume.shape, arch.max_volume, HALO)
    tally = _BrickTally()
    for i, brick in enumerate(bricks):
        part = volume.brick(brick.lo, brick.hi, brick.label)
        plan = BrickPlan(whole, brick, part)
        if not plan.ray_ids.size:
            tally.per_brick.append(
                {"index": list(brick.index), "shape": list(brick.shape), "samples": 0, "cycles": 0}
            )
            continue
        frame = frame_of(scene, part, transfer, arch, plan)
        tally.add(brick, plan, whole, frame, render_frame(frame), scene.render.mode)
        if progress is not None:
            progress(i + 1, len(bricks))
    image, touched = _blend_image(whole, tally, scene.render.mode, volume)
    counters, cycles, samples, result = tally.counters, tally.cycles, tally.samples, tally.result
    counters["supervolume.bricks"] = len(bricks)
    info = _host_info(arch, len(bricks), tally)
    counters["supervolume.host_bytes"] = info["host_bytes"]
    derived = derive(
        counters, cycles=cycles, samples=samples, pipelines=arch.pipelines, clock_hz=arch.clock_hz
    )
    # The cycles' own frame time and rate would be a second, smaller frame time beside
    # the frame's (with the host's read back): the frame's is hwsim.run.output's alone.
    del derived["frame_seconds"], derived["frames_per_second"]
    derived["supervolume"] = info
    return SupervolumeResult(
        image=image,
        samples=samples,
        rays=int(touched.sum()),
        cycles=cycles,
        counters=counters,
        derived=derived,
        elaborated_units=list(getattr(result, "elaborated_units", []) or []),
        elided_units=list(getattr(result, "elided_units", []) or []),
    )


@dataclass
class _BrickTally:
    """The bricks' renders so far: each brick's rays and pixels, and their sums."""

    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    per_brick: list[dict[str, Any]] = field(default_factory=list)
    counters: dict[str, Any] = field(default_factory=dict)
    samples: int = 0
    cycles: int = 0
    bits: int = 0  # the composite output width of the last brick rendered
    result: Any = None  # the last brick's result (its unit lists)

    def add(
        self, brick: Any, plan: BrickPlan, whole: Any, frame: Any, result: Any, mode: str
    ) -> None:
        """Add one rendered brick: its rays' pixels (composite: as output integers), keyed
        by where its rays first step so ``_blend`` orders the bricks along each ray."""
        self.result = result
        self.bits = bits = frame.datapath.composite.output_bits
        n_pix = whole.shape[0] * whole.shape[1]
        image = result.image.reshape(n_pix, -1)[plan.ray_ids]
        if mode == "composite":
            image = np.floor(image * ((1 << bits) - 1) + 0.5).astype(np.int64)
        key = plan.first_step if not whole.back_to_front else -plan.first_step
        self.parts.append((plan.ray_ids, key, image))
        brick_cycles = int(getattr(result, "cycles", 0) or 0)  # the functional rung: none
        self.samples += int(result.samples)
        self.cycles += brick_cycles
        _add_counters(self.counters, getattr(result, "counters", {}) or {})
        self.per_brick.append(
            {
                "index": list(brick.index),
                "shape": list(brick.shape),
                "samples": int(result.samples),
                "cycles": brick_cycles,
            }
        )


def _blend_image(
    whole: Any, tally: _BrickTally, mode: str, volume: Volume
) -> tuple[np.ndarray, np.ndarray]:
    """The host's blend of the bricks' pixels into the frame, and which rays it touched."""
    n_pix = whole.shape[0] * whole.shape[1]
    base, touched = _blend(tally.parts, n_pix, mode, tally.bits, volume.value_range)
    if mode == "composite":
        base = base.astype(np.float64) / ((1 << tally.bits) - 1)
        background = 0.0
    else:
        background = volume.value_range[0 if mode == "mip" else 1]
    return whole.to_image(base, background), touched


def host_seconds(derived: dict[str, Any]) -> float:
    """A frame's time apart from its machine cycles, from its ``derived`` figures: a
    supervolume's host read back of its bricks' pixels; 0 for a one-pass frame."""
    return float(derived.get("supervolume", {}).get("host_seconds", 0.0))


def _host_info(arch: ArchConfig, n_bricks: int, tally: _BrickTally) -> dict[str, Any]:
    """The ``supervolume`` block of the derived figures: the bricks, and the host bus
    moving their pixels (the frame's time adds it to the cycles: :func:`host_seconds`)."""
    pixels = sum(p[0].size for p in tally.parts)
    host_bytes = pixels * PIXEL_BYTES
    seconds = host_bytes / arch.host_bus_bytes_per_second if arch.host_bus_bytes_per_second else 0.0
    return {
        "bricks": n_bricks,
        "halo": HALO,
        "per_brick": tally.per_brick,
        "host_bytes": host_bytes,
        "host_seconds": seconds,
    }


def _blend(parts, n_pix: int, mode: str, bits: int, value_range) -> tuple[np.ndarray, np.ndarray]:
    """The host's blend of the bricks' pixels: ``(base (n_pix[, 4]), touched)``."""
    touched = np.zeros(n_pix, dtype=bool)
    if mode != "composite":
        lo, hi = value_range
        base = np.full(n_pix, lo if mode == "mip" else hi)
        pick = np.maximum if mode == "mip" else np.minimum
        for rays, _, values in parts:
            base[rays] = pick(base[rays], values[:, 0])
            touched[rays] = True
        return base, touched
    acc = np.zeros((n_pix, 4), dtype=np.int64)
    if not parts:
        return acc, touched
    rays = np.concatenate([p[0] for p in parts])
    keys = np.concatenate([p[1] for p in parts])
    rgba = np.concatenate([p[2] for p in parts])
    order = np.lexsort((keys, rays))  # by pixel, then front to back
    rays, rgba = rays[order], rgba[order]
    starts = np.flatnonzero(np.r_[True, rays[1:] != rays[:-1]])
    rank = np.arange(rays.size) - np.repeat(starts, np.diff(np.r_[starts, rays.size]))
    for r in range(int(rank.max()) + 1):
        sel = rank == r
        front = acc[rays[sel]]
        blend_unorm(front, rgba[sel], bits)
        acc[rays[sel]] = front
    touched[rays] = True
    return acc, touched


def _add_counters(total: dict[str, Any], counters: dict[str, Any]) -> None:
    """Sum the bricks' counters (peaks and depths: the largest)."""
    for key, value in counters.items():
        if isinstance(value, dict):
            _add_counters(total.setdefault(key, {}), value)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            if any(
                w in key for w in ("max", "peak", "depth", "entries", "words_per_bank", "latency")
            ):
                total[key] = max(total.get(key, value), value)
            else:
                total[key] = total.get(key, 0) + value
