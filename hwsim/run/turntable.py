"""Turntables: one scene rendered ``N`` times, the azimuth turned by a fixed step.

A classic volume-rendering output, and the honest way to time frames: the first frame
pays the set-up (volume load, per-volume derived arrays, compiled kernels), the others
reuse it, so the per-frame figure is the median of frames 2..N.  Every frame goes
through :func:`hwsim.run.fidelity.render` with the same loaded volume (the caches are keyed
by it); the frames are written as PNGs and as an animated GIF encoded by Pillow.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.run.fidelity import RenderRun, render
from hwsim.spec.scene import Scene
from hwsim.volumes import load_volume

__all__ = ["MAX_FRAMES", "render_turntable", "turntable_stats", "write_turntable"]

MAX_FRAMES = 3600
#: Playback rate of the GIF (frames per second).
GIF_FPS = 20


def _azimuth(start: float, k: int, turn: float) -> float:
    """``start + k turn`` wrapped into ``(-180, 180]`` (the scene's azimuth range)."""
    a = math.fmod(start + k * turn, 360.0)
    return a - 360.0 if a > 180.0 else a + 360.0 if a <= -180.0 else a


def render_turntable(
    scene: Scene,
    frames: int,
    turn: float,
    *,
    progress: Callable[[int, int], None] | None = None,
    **render_kw: Any,
) -> list[RenderRun]:
    """``frames`` renders of ``scene``, the azimuth turned by ``turn`` degrees each.

    ``render_kw`` go to :func:`hwsim.run.fidelity.render` (fidelity, arch, extend, ...); a
    waveform (``trace``) is refused: it would hold one frame of many.
    """
    if not 1 <= frames <= MAX_FRAMES:
        raise InputError(f"{frames} frames", key="--frames", allowed=f"1 .. {MAX_FRAMES}")
    if not math.isfinite(turn) or not -360.0 <= turn <= 360.0:
        raise InputError(f"a turn of {turn:g} degrees", key="--turn", allowed="-360 .. 360")
    if frames > 1 and render_kw.get("trace") is not None:
        raise InputError("a waveform holds one frame", key="--trace", allowed="--frames 1")
    volume = render_kw.pop("volume", None)
    if volume is None:
        volume = load_volume(scene.volume, scene.base_dir)
    runs = []
    for k in range(frames):
        view = dataclasses.replace(scene.view, azimuth=_azimuth(scene.view.azimuth, k, turn))
        runs.append(render(scene.replace(view=view), volume=volume, **render_kw))
        if progress is not None:
            progress(k + 1, frames)
    return runs


def turntable_stats(runs: list[RenderRun], turn: float) -> dict[str, Any]:
    """The ``turntable`` block of stats.json: each frame's azimuth, wall time and cycles,
    and the per-frame figure (median wall time of frames 2..N; frame 1 pays the set-up)."""
    walls = [r.wall_seconds for r in runs]
    later = walls[1:] or walls
    return {
        "frames": len(runs),
        "turn_degrees": turn,
        "azimuths": [r.scene.view.azimuth for r in runs],
        "frame_wall_seconds": walls,
        "frame_cycles": [r.cycles for r in runs],
        "median_frame_wall_seconds": statistics.median(later),
        "median_of": "frames 2..N" if len(runs) > 1 else "the only frame",
    }


def _window(images: list[np.ndarray]) -> tuple[float, float]:
    """One grey window for every frame of a scalar-image turntable (no flicker)."""
    return min(float(i.min()) for i in images), max(float(i.max()) for i in images)


def write_turntable(runs: list[RenderRun], out_dir: str | Path, turn: float) -> dict[str, Path]:
    """Frame 1's image and stats (with the ``turntable`` block), ``frames/frame_NNNN.png``
    and ``turntable.gif`` in ``out_dir``."""
    from PIL import Image

    from hwsim.run.output import image_to_rgb8, write_render

    paths = write_render(runs[0], out_dir, extra={"turntable": turntable_stats(runs, turn)})
    out = Path(out_dir)
    folder = out / "frames"
    folder.mkdir(exist_ok=True)
    images = [r.image for r in runs]
    window = _window(images) if images[0].ndim == 2 else None
    pictures = []
    for k, image in enumerate(images):
        rgb, _ = image_to_rgb8(image, window)
        picture = Image.fromarray(rgb)
        picture.save(folder / f"frame_{k:04d}.png")
        pictures.append(picture)
    gif = out / "turntable.gif"
    pictures[0].save(
        gif, save_all=True, append_images=pictures[1:], duration=1000 // GIF_FPS, loop=0
    )
    return {**paths, "frames": folder, "gif": gif}
