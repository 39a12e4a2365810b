"""Turntables: one scene rendered ``N`` times, the azimuth turned by a fixed step.

A classic volume-rendering output, and the honest way to time frames: the first frame
pays the set-up (volume load, per-volume derived arrays, compiled kernels), the others
reuse it, so the per-frame figure is the median of frames 2..N.  Every frame goes
through :func:`hwsim.run.fidelity.render` with the same loaded volume (the caches are keyed
by it).  The frames stream to disk (:func:`stream_turntable`): each PNG is written as
its frame ends and the frame let go, and the animated GIF (Pillow) is assembled from the
files at the end, so a long turntable holds one frame, not all of them; every file goes
through a temporary name (:func:`hwsim.core.paths.atomic_write`).  Every path it writes
(:func:`turntable_outputs`) is checked before the first frame.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.paths import FILE, FOLDER, atomic_write, naming, output_folder
from hwsim.run.fidelity import RenderRun, render
from hwsim.spec.scene import Scene
from hwsim.volumes import load_volume

__all__ = [
    "MAX_FRAMES",
    "FrameStats",
    "check_turntable",
    "render_turntable",
    "stream_turntable",
    "turntable_frames",
    "write_frames",
    "turntable_outputs",
    "turntable_bytes",
    "turntable_stats",
    "write_turntable",
]

MAX_FRAMES = 3600
#: Playback rate of the GIF (frames per second).
GIF_FPS = 20


def _azimuth(start: float, k: int, turn: float) -> float:
    """``start + k turn`` wrapped into ``(-180, 180]`` (the scene's azimuth range)."""
    a = math.fmod(start + k * turn, 360.0)
    return a - 360.0 if a > 180.0 else a + 360.0 if a <= -180.0 else a


def check_turntable(frames: int, turn: float, trace: str | None = None) -> None:
    """Refuse a frame count, turn or waveform a turntable cannot take (before any frame)."""
    if not 1 <= frames <= MAX_FRAMES:
        raise InputError(f"{frames} frames", key="--frames", allowed=f"1 .. {MAX_FRAMES}")
    if not math.isfinite(turn) or not -360.0 <= turn <= 360.0:
        raise InputError(f"a turn of {turn:g} degrees", key="--turn", allowed="-360 .. 360")
    if frames > 1 and trace is not None:
        raise InputError("a waveform holds one frame", key="--trace", allowed="--frames 1")


def turntable_outputs(out_dir: str | Path, frames: int) -> list[tuple[str, Path, str]]:
    """Every path :func:`write_turntable` writes for ``frames`` frames (frame 1's render
    files, ``frames/`` and each ``frame_NNNN.png`` in it, ``turntable.gif``), as
    :func:`hwsim.core.paths.plan_outputs` takes them: checked before the first frame."""
    from hwsim.run.output import render_outputs

    check_turntable(frames, 0.0)
    out = Path(out_dir)
    folder = out / "frames"
    pngs = [("--out", folder / f"frame_{k:04d}.png", FILE) for k in range(frames)]
    gif = ("--out", out / "turntable.gif", FILE)
    return [*render_outputs(out), ("--out", folder, FOLDER), *pngs, gif]


def turntable_frames(
    scene: Scene,
    frames: int,
    turn: float,
    *,
    progress: Callable[[int, int], None] | None = None,
    **render_kw: Any,
) -> Iterator[RenderRun]:
    """``frames`` renders of ``scene``, the azimuth turned by ``turn`` degrees each, one
    at a time (a caller that writes each and lets it go holds one frame in memory).

    ``render_kw`` go to :func:`hwsim.run.fidelity.render` (fidelity, arch, extend, ...); a
    waveform (``trace``) is refused: it would hold one frame of many.
    """
    check_turntable(frames, turn, render_kw.get("trace"))
    volume = render_kw.pop("volume", None)
    if volume is None:
        volume = load_volume(scene.volume, scene.base_dir)
    for k in range(frames):
        view = dataclasses.replace(scene.view, azimuth=_azimuth(scene.view.azimuth, k, turn))
        yield render(scene.replace(view=view), volume=volume, **render_kw)
        if progress is not None:
            progress(k + 1, frames)


def render_turntable(scene: Scene, frames: int, turn: float, **kw: Any) -> list[RenderRun]:
    """Every frame of :func:`turntable_frames` in a list (each with its image: for
    scripts and small frames; :func:`stream_turntable` keeps none)."""
    return list(turntable_frames(scene, frames, turn, **kw))


@dataclasses.dataclass(frozen=True)
class FrameStats:
    """What a streamed turntable keeps of a frame once it is on disk."""

    azimuth: float
    wall_seconds: float
    cycles: int | None
    #: The image's range (a scalar image's share of the common grey window).
    low: float
    high: float

    @classmethod
    def of(cls, run: RenderRun) -> FrameStats:
        image = run.image
        return cls(run.scene.view.azimuth, run.wall_seconds, run.cycles,
                   float(image.min()), float(image.max()))  # fmt: skip


def turntable_stats(frames: Sequence[FrameStats | RenderRun], turn: float) -> dict[str, Any]:
    """The ``turntable`` block of stats.json: each frame's azimuth, wall time and cycles,
    and the per-frame figure (median wall time of frames 2..N; frame 1 pays the set-up)."""
    stats = [f if isinstance(f, FrameStats) else FrameStats.of(f) for f in frames]
    walls = [f.wall_seconds for f in stats]
    later = walls[1:] or walls
    return {
        "frames": len(stats),
        "turn_degrees": turn,
        "azimuths": [f.azimuth for f in stats],
        "frame_wall_seconds": walls,
        "frame_cycles": [f.cycles for f in stats],
        "median_frame_wall_seconds": statistics.median(later),
        "median_of": "frames 2..N" if len(stats) > 1 else "the only frame",
    }


def turntable_bytes(frames: int, height: int, width: int) -> int:
    """Bytes a streamed turntable holds besides the frame being rendered: frame 1's
    image (float64 RGBA) and the GIF encoder's frames (Pillow keeps each frame, one byte
    a pixel, until it writes the file) and one frame's RGB and PNG buffers."""
    return height * width * (32 + frames + 2 * 3)


def stream_turntable(
    scene: Scene, frames: int, turn: float, out_dir: str | Path, **kw: Any
) -> tuple[RenderRun, list[FrameStats], dict[str, Path]]:
    """Render a turntable into ``out_dir`` a frame at a time: ``frames/frame_NNNN.png``
    as each frame ends (a scalar image's frames wait, as raw floats on disk, for the
    grey window they share), then ``turntable.gif`` from the PNGs on disk and frame 1's
    files with the ``turntable`` block.  Memory is one frame, frame 1's image and the
    GIF encoder's bytes (:func:`turntable_bytes`), checked against the budget first.

    Returns frame 1's run, every frame's :class:`FrameStats` and the paths written.
    """
    from hwsim.core.budget import require_fits

    view = scene.view
    require_fits(turntable_bytes(frames, view.height, view.width),
                 what=f"a turntable of {frames} frames {view.width}x{view.height} (besides "
                 "each frame)", key="--frames")  # fmt: skip
    return write_frames(turntable_frames(scene, frames, turn, **kw), out_dir, turn)


def write_frames(
    runs: Iterable[RenderRun], out_dir: str | Path, turn: float
) -> tuple[RenderRun, list[FrameStats], dict[str, Path]]:
    """Write each run of ``runs`` as it comes (see :func:`stream_turntable`), keeping only
    the first run and each frame's :class:`FrameStats`."""
    from hwsim.run.output import write_render

    out = Path(out_dir)
    folder = output_folder(out / "frames")
    first, stats = None, []
    with tempfile.TemporaryDirectory(dir=out, prefix=".frames-") as scratch:
        for run in runs:  # not enumerate: its reused tuple would hold the last frame
            k, first = len(stats), first or run
            stats.append(FrameStats.of(run))
            if run.image.ndim == 2:  # a scalar image: its PNG needs every frame's range
                with naming(Path(scratch) / f"{k:04d}.npy"):  # no space: which file
                    np.save(Path(scratch) / f"{k:04d}.npy", run.image.astype(np.float32))
            else:
                _write_png(run.image, None, folder / f"frame_{k:04d}.png")
            del run
        if first is not None and first.image.ndim == 2:
            window = min(f.low for f in stats), max(f.high for f in stats)
            for k in range(len(stats)):
                image = np.load(Path(scratch) / f"{k:04d}.npy")
                _write_png(image, window, folder / f"frame_{k:04d}.png")
    if first is None:
        raise InputError("no frames", key="--frames", allowed=f"1 .. {MAX_FRAMES}")
    pngs = [folder / f"frame_{k:04d}.png" for k in range(len(stats))]
    gif = _write_gif(pngs, out / "turntable.gif")
    paths = write_render(first, out, extra={"turntable": turntable_stats(stats, turn)})
    return first, stats, {**paths, "frames": folder, "gif": gif}


def write_turntable(runs: list[RenderRun], out_dir: str | Path, turn: float) -> dict[str, Path]:
    """Frame 1's image and stats (with the ``turntable`` block), ``frames/frame_NNNN.png``
    and ``turntable.gif`` in ``out_dir``, from runs already in memory."""
    return write_frames(runs, out_dir, turn)[2]


def _write_png(image: np.ndarray, window: tuple[float, float] | None, path: Path) -> None:
    from PIL import Image

    from hwsim.run.output import image_to_rgb8

    rgb, _ = image_to_rgb8(image, window)
    with atomic_write(path) as tmp:
        Image.fromarray(rgb).save(tmp, format="PNG")


def _write_gif(pngs: list[Path], gif: Path) -> Path:
    """``gif`` animated from the frames' PNG files, read one at a time."""
    from PIL import Image

    def read(path: Path) -> Image.Image:
        with Image.open(path) as picture:
            picture.load()
            return picture.copy()

    with atomic_write(gif) as tmp:
        read(pngs[0]).save(
            tmp,
            format="GIF",
            save_all=True,
            append_images=(read(p) for p in pngs[1:]),
            duration=1000 // GIF_FPS,
            loop=0,
        )
    return gif
