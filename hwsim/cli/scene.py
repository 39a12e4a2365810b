"""The scene flags ``hwsim render`` and ``hwsim rtl diff`` share (applied to a loaded scene
by :func:`hwsim.spec.overrides.apply_overrides`)."""

from __future__ import annotations

import argparse

__all__ = ["add_scene_options"]


def add_scene_options(p: argparse.ArgumentParser) -> None:
    """The scene and its overrides (``render``, ``rtl diff``)."""
    from hwsim.spec.scene import MODES, PROJECTIONS, TF_PRESETS

    p.add_argument("scene", nargs="?", help="scene TOML file or built-in name (default: head)")
    src = p.add_mutually_exclusive_group()
    src.add_argument(
        "--volume",
        metavar="PATH",
        help="render this volume file (.nrrd, .nii, .npy, .raw, ...) or DICOM folder instead "
        "of the scene's",
    )
    src.add_argument(
        "--phantom",
        metavar="NAME[:key=value,...]",
        help="render a built-in phantom instead of the scene's volume, e.g. head:size=64 "
        "(hwsim phantoms lists them)",
    )
    p.add_argument("--shape", metavar="Z,Y,X", help="shape of a headerless .raw volume")
    p.add_argument("--dtype", help="voxel type of a .raw volume (e.g. uint16)")
    p.add_argument(
        "--mode",
        choices=MODES,
        help="what a ray reports: composite (shaded, translucent), maximum/minimum intensity, "
        "x-ray sum or iso surface (default: the scene's, composite for head)",
    )
    p.add_argument(
        "--view",
        metavar="AZ,EL",
        help="view direction: azimuth,elevation in degrees (default: the scene's, 30,15 for head)",
    )
    p.add_argument(
        "--image",
        metavar="W[xH]",
        help="image size in pixels, e.g. 128 or 320x240 (default: the scene's, 256 for head)",
    )
    p.add_argument(
        "--projection",
        choices=PROJECTIONS,
        help="parallel rays or a perspective camera (default: the scene's, parallel for head)",
    )
    p.add_argument(
        "--transfer",
        metavar="PRESET|FILE",
        help=f"transfer function: a preset ({', '.join(TF_PRESETS)}), a transfer TOML "
        "(the keys of a scene's [transfer]) or an (N, 4) .npy table",
    )
