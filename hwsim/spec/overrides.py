"""A scene's overrides as the command line spells them (``--view 30,10``, ``--image 256x128``,
``--volume ct.nrrd``, ``--phantom head:size=64``): parsed, range-checked and applied to a
loaded scene, every bad value a one-line error naming the flag.  ``hwsim render`` and
``hwsim rtl diff`` pass their parsed arguments; :func:`hwsim.load_scene` passes
:class:`SceneFlags` built from its keywords."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Protocol

from hwsim.core.errors import InputError

__all__ = ["SceneFlags", "apply_overrides"]


@dataclasses.dataclass(frozen=True)
class SceneFlags:
    """The scene flags as text (None: keep the scene's value)."""

    volume: str | None = None
    phantom: str | None = None
    shape: str | None = None
    dtype: str | None = None
    mode: str | None = None
    view: str | None = None
    image: str | None = None
    projection: str | None = None


class _Flags(Protocol):
    volume: str | None
    phantom: str | None
    shape: str | None
    dtype: str | None
    mode: str | None
    view: str | None
    image: str | None
    projection: str | None


def apply_overrides(scene: Any, args: _Flags) -> Any:
    """Every flag given (not None) overrides the scene's value."""
    from hwsim.core.config import check_number
    from hwsim.spec.scene import MAX_IMAGE, VolumeSpec
    from hwsim.volumes import parse_phantom_spec

    if args.volume is not None:
        if not args.volume.strip():
            raise InputError("empty path", key="--volume", allowed="a volume file or DICOM folder")
        shape = _ints(args.shape, "--shape", 3) if args.shape is not None else None
        spec = VolumeSpec(path=str(Path(args.volume).resolve()), shape=shape, dtype=args.dtype)
        scene = scene.replace(volume=spec)
    elif args.shape is not None or args.dtype is not None:
        raise InputError("only valid with --volume FILE.raw", key="--shape/--dtype")
    if args.phantom:
        name, params = parse_phantom_spec(args.phantom)
        scene = scene.replace(volume=VolumeSpec(phantom=name, params=tuple(sorted(params.items()))))
    render_spec, view = scene.render, scene.view
    if args.mode:
        render_spec = dataclasses.replace(render_spec, mode=args.mode)
    if args.view is not None:
        parts = args.view.split(",")
        if len(parts) != 2:
            raise InputError(
                f"expected AZ,EL, got {args.view!r}", key="--view", allowed="-360 .. 360, -90 .. 90"
            )
        az = check_number(_float(parts[0], "--view"), "--view", "azimuth", -360, 360)
        el = check_number(_float(parts[1], "--view"), "--view", "elevation", -90, 90)
        view = dataclasses.replace(view, azimuth=az, elevation=el)
    if args.image is not None:
        text = args.image.lower()
        w, h = text.split("x", 1) if "x" in text else (text, text)
        width = _int_in(w, "--image", 1, MAX_IMAGE)
        height = _int_in(h, "--image", 1, MAX_IMAGE)
        view = dataclasses.replace(view, width=width, height=height)
    if args.projection:
        view = dataclasses.replace(view, projection=args.projection)
    return scene.replace(render=render_spec, view=view)


def _float(text: str, flag: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{text!r} is not a number", key=flag) from None


def _int_in(text: str, flag: str, lo: int, hi: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise InputError(f"{text!r} is not an integer", key=flag, allowed=f"{lo} .. {hi}") from None
    if not lo <= value <= hi:
        raise InputError(f"{value} is out of range", key=flag, allowed=f"{lo} .. {hi}")
    return value


def _ints(text: str, flag: str, count: int) -> tuple[int, ...]:
    parts = text.split(",")
    if len(parts) != count:
        raise InputError(f"expected {count} comma-separated integers, got {text!r}", key=flag)
    return tuple(_int_in(p, flag, 1, 1 << 16) for p in parts)
