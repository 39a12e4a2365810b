"""Writing one render's outputs: ``image.npy``, ``image.png`` and ``stats.json``.

Derived metrics (``frame_seconds``, ``samples_per_second``) are computed here and only
here, from the raw counts a rung returns.  Files are written in the order
``image.npy``, ``image.png``, ``stats.json``, each through a temporary name and an
atomic rename, so an interrupted write never leaves a half file and never loses what
was already computed.
"""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hwsim import __version__
from hwsim.core.errors import InputError
from hwsim.core.paths import display_path, output_file, output_folder
from hwsim.core.threads import frame_threads

if TYPE_CHECKING:
    from hwsim.run.fidelity import RenderRun
    from hwsim.spec.scene import Scene

__all__ = [
    "STATS_SCHEMA",
    "frame_timing",
    "stats_dict",
    "stats_plain",
    "transfer_stats",
    "write_render",
    "image_to_rgb8",
    "output_folder",
    "output_file",
]

STATS_SCHEMA = 1


def frame_timing(run: RenderRun) -> dict[str, float | None]:
    """A frame's simulated time and rate, computed here once for ``stats.json`` and the
    render summary: the machine's (its cycles at its clock) and the frame's, which adds
    the time the host spends on it (a supervolume's read back of its bricks' pixels,
    :func:`hwsim.run.supervolume.host_seconds`; 0 otherwise).  All None when untimed."""
    from hwsim.run.supervolume import host_seconds

    keys = ("machine_frame_seconds", "machine_frames_per_second", "host_seconds")
    keys += ("frame_seconds", "frames_per_second")
    if run.cycles is None or not run.clock_hz:
        return dict.fromkeys(keys)
    machine = run.cycles / run.clock_hz
    host = host_seconds(run.derived)
    frame = machine + host
    return dict(
        zip(keys, (machine, 1.0 / machine if machine else 0.0, host, frame,
                   1.0 / frame if frame else 0.0), strict=True)
    )  # fmt: skip


def stats_dict(run: RenderRun, base: str | Path | None = None) -> dict[str, Any]:
    """The ``stats.json`` content of a render (design section 9).

    Its paths (the scene file, the volume) are recorded relative to ``base`` (the run
    folder), the repository or the working folder (:func:`hwsim.core.paths.display_path`),
    never as this machine's absolute paths.
    """
    timing = frame_timing(run)
    frame_seconds = timing["frame_seconds"]
    sps = run.samples / frame_seconds if frame_seconds else None
    vol = run.volume
    scene = run.scene.to_dict()
    scene["source"] = display_path(scene["source"], base)
    if scene["volume"].get("path"):
        scene["volume"]["path"] = display_path(scene["volume"]["path"], base)
    return {
        "schema": STATS_SCHEMA,
        "hwsim_version": __version__,
        "fidelity": run.fidelity,
        "arch": run.arch,
        "sampling": run.sampling,
        "scene": scene,
        "transfer": transfer_stats(run.scene),  # the preset and why (auto's choice)
        "volume": {
            "name": vol.name,
            "source": display_path(vol.source, base),
            "shape_zyx": list(vol.shape),
            "spacing_zyx": list(vol.spacing),
            "dtype": str(vol.data.dtype),
            "bits": vol.bits,
            "units": vol.units,
            "value_range": list(vol.value_range),
            # A field's volume (value_field): the width of the whole voxels it came from.
            "container_bits": vol.meta.get("container_bits"),
        },
        "image": None
        if run.image is None
        else {"shape": list(run.image.shape), "dtype": str(run.image.dtype)},
        "samples": run.samples,
        "rays": run.rays,
        "cycles": run.cycles,
        "clock_hz": run.clock_hz,
        **timing,  # the frame's seconds and fps, and the machine's alone (frame_timing)
        "samples_per_second": sps,
        "wall_seconds": run.wall_seconds,
        "wall_samples_per_second": run.samples / run.wall_seconds if run.wall_seconds else None,
        "elaborated_units": run.elaborated_units,
        "elided_units": run.elided_units,
        "counters": run.counters,
        "derived": run.derived,
        "extensions": run.extensions,  # features outside the machine (a what-if render)
        "shading": run.shading,
        # Energy per frame and silicon area (hwsim.energy; None: no actions counted).
        "technology": run.silicon["technology"] if run.silicon else None,
        "energy": run.silicon["energy"] if run.silicon else None,
        "area": run.silicon["area"] if run.silicon else None,
        # A frame split across workers: each band's rays, seconds and peak memory.
        "split": run.split,
        "host": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "machine": platform.machine(),
            "frame_threads": frame_threads(),  # the frame kernels' threads (--threads)
        },
    }


def transfer_stats(scene: Scene) -> dict[str, Any]:
    """Which transfer function a render used and why: ``preset`` (None for a scene's own
    points or table, or its ``[classification]`` LUTs) and ``chosen_by`` (``"scene"`` when
    the scene names it, ``"auto: ..."`` when :mod:`hwsim.spec.preset_choice` chose it)."""
    spec = scene.transfer
    if scene.classification is not None:
        return {"preset": None, "chosen_by": "scene [classification] LUTs"}
    if spec.points is not None or spec.table is not None:
        kind = "points" if spec.points is not None else "table"
        return {"preset": None, "chosen_by": f"scene transfer.{kind}"}
    return {"preset": spec.preset, "chosen_by": spec.chosen_by or "scene"}


def stats_plain(run: RenderRun, base: str | Path | None = None) -> dict[str, Any]:
    """:func:`stats_dict` as plain JSON types (NumPy scalars and arrays converted)."""
    return json.loads(json.dumps(stats_dict(run, base), default=_json_default))


def image_to_rgb8(
    image: np.ndarray, window: tuple[float, float] | None = None
) -> tuple[np.ndarray, dict[str, Any]]:
    """An 8-bit picture of a render and how it was made.

    RGBA images (premultiplied) are shown over black; scalar images (mip, minip, xray)
    are windowed linearly from their minimum to their maximum, or over ``window``.
    """
    if image.ndim == 3:
        rgb = np.clip(image[..., :3], 0.0, 1.0)
        return np.round(rgb * 255.0).astype(np.uint8), {"display": "rgb over black"}
    lo, hi = window if window is not None else (float(image.min()), float(image.max()))
    scaled = np.clip((image - lo) / (hi - lo), 0.0, 1.0) if hi > lo else np.zeros_like(image)
    grey = np.round(scaled * 255.0).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2), {"display": "grey", "window": [lo, hi]}


def _atomic_write(path: Path, write) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    write(tmp)
    os.replace(tmp, path)


def write_render(
    run: RenderRun, out_dir: str | Path, extra: dict[str, Any] | None = None
) -> dict[str, Path]:
    """Write ``image.npy``, ``image.png`` and ``stats.json`` (plus ``extra`` blocks, e.g.
    a turntable's) into ``out_dir``; ``stats.json`` alone for a frame timed without its
    image."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import image as mpimage

    out = output_folder(out_dir)
    paths = {"npy": out / "image.npy", "png": out / "image.png", "stats": out / "stats.json"}
    try:
        stats = stats_dict(run, out)
        if run.image is None:  # timed without its image: stats only
            del paths["npy"], paths["png"]
        else:

            def save_npy(p: Path) -> None:
                with open(p, "wb") as fh:
                    np.save(fh, run.image, allow_pickle=False)

            _atomic_write(paths["npy"], save_npy)
            rgb, display = image_to_rgb8(run.image)
            _atomic_write(paths["png"], lambda p: mpimage.imsave(p, rgb, format="png"))
            stats["image"].update(display)
        stats.update(extra or {})
        text = json.dumps(stats, indent=2, default=_json_default)
        _atomic_write(paths["stats"], lambda p: p.write_text(text + "\n"))
        from hwsim.run.output_csvs import write_csvs

        paths.update(write_csvs(run, out))
    except OSError as exc:
        raise InputError(
            f"cannot write output: {exc.strerror}", source=str(out), key="--out"
        ) from None
    return paths


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot serialise {type(value).__name__}")
