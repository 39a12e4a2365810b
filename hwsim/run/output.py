"""Writing one render's outputs: ``image.npy``, ``image.png`` and ``stats.json``.

Derived metrics (``frame_seconds``, ``samples_per_second``) are computed here and only
here, from the raw counts a rung returns.  Files are written in the order
``image.npy``, ``image.png``, ``stats.json``, each through a temporary name and an
atomic rename (:func:`hwsim.core.paths.atomic_write`), so an interrupted write never
leaves a half file or destroys an earlier result, and one file that fails does not stop
the others: what was computed is kept.  :func:`render_outputs` lists every path a
render writes, for the command to check before the frame.
"""

from __future__ import annotations

import dataclasses
import json
import platform
from collections.abc import Iterator
from contextlib import suppress
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hwsim import __version__
from hwsim.core.errors import HwsimError, InputError
from hwsim.core.paths import (
    atomic_write,
    display_path,
    in_folder,
    output_file,
    output_folder,
    plan_outputs,
    write_text_atomic,
)
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
    "render_outputs",
    "scene_inputs",
    "CSV_NAMES",
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


#: The CSVs a timed run writes next to its image (:mod:`hwsim.run.output_csvs`).
CSV_NAMES = ("throughput.csv", "units.csv", "memory.csv")


def render_outputs(out_dir: str | Path, key: str = "--out") -> list[tuple[str, Path, str]]:
    """Every path :func:`write_render` may write in ``out_dir``, as
    :func:`hwsim.core.paths.plan_outputs` takes them (checked before the frame)."""
    names = ("image.npy", "image.png", "stats.json", *CSV_NAMES)
    return in_folder(key, out_dir, (Path(out_dir) / name for name in names))


def scene_inputs(scene: Scene) -> list[tuple[str, Path | None]]:
    """The files a render of ``scene`` reads: the scene file, its volume (a file or a
    DICOM folder) and every file a value of the scene names (a transfer table, geometry
    buffers, whatever key names one), as :func:`hwsim.core.paths.plan_outputs` takes
    them; the files read while it loads are recorded by the loaders themselves."""
    source = None if scene.source.startswith("<") else Path(scene.source)
    volume = scene.volume.path
    if volume:
        volume = Path(volume).expanduser()
        volume = volume if volume.is_absolute() else scene.base_dir / volume
    named = _named_files(scene, scene.base_dir, "")
    return [("scene", source), ("volume", volume), *named]


def _named_files(value: Any, base: Path, key: str) -> Iterator[tuple[str, Path]]:
    """(key path, file) for every string in ``value`` (a scene's dataclasses or structs, tuples
    and dicts, walked whole) that names an existing file, relative to ``base`` unless
    absolute: files a scene names are inputs whichever key names them."""
    if isinstance(value, type):
        return
    names = getattr(value, "__struct_fields__", None)  # a msgspec.Struct
    if names is None and dataclasses.is_dataclass(value):
        names = [f.name for f in dataclasses.fields(value)]
    if names is not None:
        for name in names:
            if name not in ("name", "source"):
                yield from _named_files(getattr(value, name), base, f"{key}.{name}".lstrip("."))
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _named_files(item, base, key)
    elif isinstance(value, dict):
        for name, item in value.items():
            yield from _named_files(item, base, f"{key}.{name}".lstrip("."))
    elif isinstance(value, (str, Path)) and 0 < len(str(value)) < 4096:
        with suppress(OSError, ValueError, RuntimeError):  # too long, a NUL, no ~user
            path = Path(value).expanduser()
            path = path if path.is_absolute() else base / path
            if path.is_file():
                yield key, path


def _save_npy(image: np.ndarray, path: Path) -> None:
    with atomic_write(path) as tmp, open(tmp, "wb") as fh:
        np.save(fh, image, allow_pickle=False)


def _save_png(rgb: np.ndarray, path: Path) -> None:
    from matplotlib import image as mpimage

    with atomic_write(path) as tmp:
        mpimage.imsave(tmp, rgb, format="png")


def write_render(
    run: RenderRun, out_dir: str | Path, extra: dict[str, Any] | None = None
) -> dict[str, Path]:
    """Write ``image.npy``, ``image.png`` and ``stats.json`` (plus ``extra`` blocks, e.g.
    a turntable's) into ``out_dir``; ``stats.json`` alone for a frame timed without its
    image.

    Each file is written through :func:`hwsim.core.paths.atomic_write`.  A file that
    fails does not stop the others (the frame's numbers are kept); the error then says
    which file failed and which were saved.
    """
    import matplotlib

    matplotlib.use("Agg")
    from hwsim.run.output_csvs import write_csvs

    plan_outputs(scene_inputs(run.scene), render_outputs(out_dir))  # never onto an input
    out = Path(out_dir)
    paths = {"npy": out / "image.npy", "png": out / "image.png", "stats": out / "stats.json"}
    stats = stats_dict(run, out)
    steps = []
    if run.image is None:  # timed without its image: stats only
        del paths["npy"], paths["png"]
    else:
        rgb, display = image_to_rgb8(run.image)
        stats["image"].update(display)
        steps += [("npy", lambda: _save_npy(run.image, paths["npy"]))]
        steps += [("png", lambda: _save_png(rgb, paths["png"]))]
    stats.update(extra or {})
    text = json.dumps(stats, indent=2, default=_json_default) + "\n"
    steps += [("stats", lambda: write_text_atomic(paths["stats"], text))]
    steps += [("csvs", lambda: paths.update(write_csvs(run, out)))]
    failed = None
    for name, step in steps:
        try:
            step()
        except Exception as exc:  # keep writing the rest, then say what failed
            failed = failed or (name, exc)
            paths.pop(name, None)
    if failed is not None:
        _raise_write_failure(out, failed, paths)
    return paths


def _raise_write_failure(out: Path, failed: tuple[str, Exception], paths: dict) -> None:
    """One line: which output could not be written, why, and what was saved."""
    name, exc = failed
    saved = ", ".join(p.name for p in paths.values()) or "nothing"
    what = {"csvs": "the CSVs"}.get(name, f"image.{name}" if name != "stats" else "stats.json")
    if isinstance(exc, OSError):
        raise InputError(
            f"cannot write {what}: {exc.strerror or exc}; saved {saved}",
            source=str(out),
            key="--out",
        ) from None
    raise HwsimError(
        f"writing {what} failed ({type(exc).__name__}: {exc}); saved {saved} in {out}"
    ) from exc


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot serialise {type(value).__name__}")
