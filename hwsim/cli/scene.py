"""The scene flags ``hwsim render`` and ``hwsim rtl diff`` share: the parser options and
how they override a loaded scene (every bad value a one-line error naming the flag)."""

from __future__ import annotations

import argparse
from pathlib import Path

from hwsim.core.errors import InputError

__all__ = ["add_scene_options", "apply_overrides"]


def add_scene_options(p: argparse.ArgumentParser) -> None:
    """The scene and its overrides (``render``, ``rtl diff``; read by apply_overrides)."""
    from hwsim.spec.scene import MODES, PROJECTIONS

    p.add_argument("scene", nargs="?", help="scene TOML file or built-in name (default: head)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--volume", metavar="PATH", help="volume file or DICOM folder")
    src.add_argument("--phantom", metavar="NAME[:key=value,...]", help="built-in phantom")
    p.add_argument("--shape", metavar="Z,Y,X", help="shape of a headerless .raw volume")
    p.add_argument("--dtype", help="voxel type of a .raw volume (e.g. uint16)")
    p.add_argument("--mode", choices=MODES)
    p.add_argument("--view", metavar="AZ,EL", help="azimuth,elevation in degrees")
    p.add_argument("--image", metavar="W[xH]", help="image size in pixels")
    p.add_argument("--projection", choices=PROJECTIONS)


def apply_overrides(scene, args: argparse.Namespace):
    """Every flag given on the command line overrides the scene's value."""
    import dataclasses

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
