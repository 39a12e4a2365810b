"""A scene's overrides as the command line spells them (``--view 30,10``, ``--image 256x128``,
``--volume ct.nrrd``, ``--phantom head:size=64``, ``--transfer mr``): parsed, checked by the
scene file's model (:mod:`hwsim.spec.scene_schema`: a flag and the key it overrides share
one type and range) and applied to a loaded scene, every bad value a one-line error naming
the flag.  ``hwsim
render`` and ``hwsim rtl diff`` pass their parsed arguments; :func:`hwsim.load_scene`
passes :class:`SceneFlags` built from its keywords."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Protocol

from hwsim.core.errors import InputError
from hwsim.core.models import validate
from hwsim.core.paths import file_kind, input_file

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
    transfer: str | None = None


class _Flags(Protocol):
    volume: str | None
    phantom: str | None
    shape: str | None
    dtype: str | None
    mode: str | None
    view: str | None
    image: str | None
    projection: str | None
    transfer: str | None


def apply_overrides(scene: Any, args: _Flags) -> Any:
    """Every flag given (not None) overrides the scene's value."""
    from hwsim.spec.scene import VolumeSpec
    from hwsim.spec.scene_schema import RenderModel, ViewModel, VolumeModel
    from hwsim.volumes import parse_phantom_spec

    if args.volume is not None:
        if not args.volume.strip():
            raise InputError("empty path", key="--volume", allowed="a volume file or DICOM folder")
        shape = None
        if args.shape is not None:
            shape = _ints(args.shape, "--shape", 3)
            _check("--shape", VolumeModel, shape=list(shape))
        spec = VolumeSpec(path=str(Path(args.volume).resolve()), shape=shape, dtype=args.dtype)
        scene = scene.replace(volume=spec)
    elif args.shape is not None or args.dtype is not None:
        raise InputError("only valid with --volume FILE.raw", key="--shape/--dtype")
    if args.phantom:
        name, params = parse_phantom_spec(args.phantom)
        scene = scene.replace(volume=VolumeSpec(phantom=name, params=tuple(sorted(params.items()))))
    render_spec, view = scene.render, scene.view
    if args.mode:
        _check("--mode", RenderModel, mode=args.mode)
        render_spec = dataclasses.replace(render_spec, mode=args.mode)
    if args.view is not None:
        parts = args.view.split(",")
        if len(parts) != 2:
            raise InputError(
                f"expected AZ,EL, got {args.view!r}", key="--view", allowed="-360 .. 360, -90 .. 90"
            )
        az, el = _float(parts[0], "--view"), _float(parts[1], "--view")
        validate({"azimuth": az, "elevation": el}, ViewModel, "--view")  # names the angle
        view = dataclasses.replace(view, azimuth=az, elevation=el)
    if args.image is not None:
        text = args.image.lower()
        w, h = text.split("x", 1) if "x" in text else (text, text)
        width, height = _int(w, "--image"), _int(h, "--image")
        _check("--image", ViewModel, width=width, height=height)
        view = dataclasses.replace(view, width=width, height=height)
    if args.projection:
        _check("--projection", ViewModel, projection=args.projection)
        view = dataclasses.replace(view, projection=args.projection)
    if args.transfer is not None:
        scene = scene.replace(transfer=_transfer(scene, args.transfer))
    return scene.replace(render=render_spec, view=view)


def _transfer(scene: Any, text: str) -> Any:
    """``--transfer PRESET|FILE``: a named preset, a transfer-function TOML (the keys of a
    scene's ``[transfer]``) or an ``(N, 4)`` ``.npy`` table.  A preset or table keeps the
    scene's gradient modulation and classification order."""
    from hwsim.spec.scene import TF_PRESETS, TransferSpec, load_transfer

    allowed = f"{', '.join(TF_PRESETS)}, a transfer FILE.toml or a table FILE.npy"
    if scene.classification is not None:
        raise InputError(
            "the scene's [classification] LUTs replace its transfer function",
            key="--transfer",
            allowed="a scene without [classification]",
        )
    text = text.strip()
    kind = Path(text).suffix.lower()
    if kind in (".toml", ".npy") or "/" in text:
        path = Path(text).expanduser().resolve()
        if kind not in (".toml", ".npy") or file_kind(path, "--transfer") is None:
            why = "file not found" if kind in (".toml", ".npy") else "not a .toml or .npy file"
            raise InputError(why, source=str(path), key="--transfer", allowed=allowed)
        input_file(path, "--transfer")  # a folder, a FIFO or a device: refused unopened
        if kind == ".toml":
            return load_transfer(path)
    elif text not in TF_PRESETS:
        raise InputError(f"unknown preset {text!r}", key="--transfer", allowed=allowed)
    old = scene.transfer
    keep = {
        "gradient_opacity": old.gradient_opacity,
        "order": old.order,
        "gradient_illumination": old.gradient_illumination,
    }
    if kind == ".npy":
        return TransferSpec(preset=None, table=str(path), **keep)
    return TransferSpec(preset=text, **keep)


def _float(text: str, flag: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{text!r} is not a number", key=flag) from None


def _int(text: str, flag: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise InputError(f"{text!r} is not an integer", key=flag) from None


def _ints(text: str, flag: str, count: int) -> tuple[int, ...]:
    parts = text.split(",")
    if len(parts) != count:
        raise InputError(f"expected {count} comma-separated integers, got {text!r}", key=flag)
    return tuple(_int(p, flag) for p in parts)


def _check(flag: str, model: Any, **values: Any) -> None:
    """``values`` (keys of the scene file) by the file's ``model``; a bad one is refused
    naming ``flag``, with the range the file's key allows."""
    try:
        validate(values, model, flag)
    except InputError as exc:
        raise InputError(exc.message, key=flag, allowed=exc.allowed) from None
