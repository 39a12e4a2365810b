"""Scene = volume + transfer function + view + lights + material + render mode.

A scene is versioned TOML (``schema = 1``) validated against its model
(:mod:`hwsim.spec.scene_schema`: every key's type, range and choices) and built into the
frozen dataclasses below, whose defaults fill the keys a file leaves out; a bad value
raises :class:`hwsim.core.errors.InputError` naming the file, the key path and what is
allowed.  The format is documented in ``docs/scenes.md``.

Vectors a user writes are in ``(x, y, z)`` order (light directions, cut-plane normals);
arrays are ``(z, y, x)``.  Crop limits are named per axis (``crop.x = [lo, hi]``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from msgspec import UNSET

from hwsim.core.config import read_toml
from hwsim.core.errors import InputError
from hwsim.core.models import validate
from hwsim.spec.scene_cursor import CursorSpec, parse_cursor
from hwsim.spec.scene_features import (
    ClassificationSpec,
    GeometrySpec,
    parse_classification,
    parse_geometry,
)
from hwsim.spec.scene_schema import (
    BLEND_ORDERS,
    CLASSIFICATION_ORDERS,
    CROP_MODES,
    GRADIENT_SOURCES,
    INTERPOLATIONS,
    MAX_IMAGE,
    MODES,
    PROJECTIONS,
    SCHEMA,
    TF_PRESETS,
    SceneFile,
    TransferFile,
    TransferModel,
    given,
)

__all__ = [
    "MODES",
    "BLEND_ORDERS",
    "PROJECTIONS",
    "INTERPOLATIONS",
    "GRADIENT_SOURCES",
    "CLASSIFICATION_ORDERS",
    "TF_PRESETS",
    "VolumeSpec",
    "TransferSpec",
    "ViewSpec",
    "Light",
    "Material",
    "RenderSpec",
    "CropSpec",
    "CutPlane",
    "Scene",
    "load_scene",
    "load_transfer",
    "parse_scene",
    "builtin_scenes",
    "DEFAULT_SCENE",
    "SCHEMA",
    "MAX_IMAGE",
    "CROP_MODES",
]

DEFAULT_SCENE = "head"


@dataclass(frozen=True, kw_only=True)
class VolumeSpec:
    """Where the volume comes from: exactly one of ``path`` or ``phantom``.

    ``params`` are phantom parameters (``size``, ...).  ``shape`` / ``dtype`` /
    ``byte_order`` / ``header_bytes`` describe a headerless ``.raw`` file; ``spacing``
    (``(z, y, x)``), when given, overrides the spacing a file declares.
    """

    path: str | None = None
    phantom: str | None = None
    params: tuple[tuple[str, Any], ...] = ()
    shape: tuple[int, int, int] | None = None
    dtype: str | None = None
    byte_order: str = "little"
    header_bytes: int = 0
    spacing: tuple[float, float, float] | None = None

    def describe(self) -> str:
        if self.phantom:
            args = ",".join(f"{k}={v}" for k, v in self.params)
            return f"{self.phantom}:{args}" if args else self.phantom
        return str(self.path)


@dataclass(frozen=True, kw_only=True)
class TransferSpec:
    """Classification: RGBA over voxel value, optionally modulated by gradient magnitude.

    Exactly one source: ``points`` (piecewise-linear ``[value, r, g, b, a]`` rows,
    values ascending, colours and opacity in 0..1), ``table`` (a ``.npy`` file of shape
    ``(N, 4)`` in 0..1 spread evenly over ``table_range``), or a ``preset``.  Opacity is
    defined per unit sample distance (one smallest-voxel spacing) and corrected for
    other spacings.  ``gradient_opacity`` rows are ``[|grad| in value units per world
    unit, factor 0..1]``; ``gradient_illumination`` rows the same, scaling a lit sample's
    diffuse and specular light (VolumePro 500's gradient-magnitude illumination
    modulation).  ``chosen_by`` is why a render has this preset: empty when the scene
    names it, ``"auto: ..."`` when :func:`hwsim.spec.preset_choice.resolve_auto` chose it
    (not compared: a scene rendered with the chosen preset equals one naming it).
    """

    preset: str | None = "auto"
    points: tuple[tuple[float, float, float, float, float], ...] | None = None
    table: str | None = None
    table_range: tuple[float, float] | None = None
    gradient_opacity: tuple[tuple[float, float], ...] | None = None
    order: str = "post"
    gradient_illumination: tuple[tuple[float, float], ...] | None = None
    chosen_by: str = field(default="", compare=False)


@dataclass(frozen=True, kw_only=True)
class ViewSpec:
    """Camera.  ``azimuth``/``elevation`` in degrees: ``0,0`` looks along +z, azimuth turns
    the view direction about y toward +x, elevation tilts it toward +y.  ``zoom`` scales
    the image (1 = the volume's bounding sphere fills the shorter image side).
    Perspective: ``fov`` is the full vertical angle in degrees, the eye sits
    ``distance`` bounding-sphere radii from the volume centre.
    """

    azimuth: float = 30.0
    elevation: float = 20.0
    projection: str = "parallel"
    fov: float = 30.0
    distance: float = 3.0
    zoom: float = 1.0
    width: int = 256
    height: int = 256


@dataclass(frozen=True, kw_only=True)
class Light:
    """A directional light.  ``direction`` points toward the light, ``(x, y, z)``, in view
    space (x right, y up, z toward the viewer) unless ``space = "world"``."""

    direction: tuple[float, float, float] = (-0.4, 0.5, 1.0)
    intensity: float = 1.0
    space: str = "view"


@dataclass(frozen=True, kw_only=True)
class Material:
    """Phong coefficients (Blinn half-vector form)."""

    ambient: float = 0.15
    diffuse: float = 0.7
    specular: float = 0.3
    shininess: float = 24.0


@dataclass(frozen=True, kw_only=True)
class RenderSpec:
    """How rays are sampled and combined.

    ``sample_spacing`` is in units of the smallest voxel spacing; ``supersampling``
    divides it (VolumePro's z-supersampling); ``early_termination`` stops a ray once its
    accumulated opacity reaches it (1.0 = off).  ``blend_order`` is the compositing
    order of ``composite`` mode: ``back-to-front`` walks every ray from its far end (the
    machine's slices in reverse) and blends ``C = a c + (1 - a) C``; it cannot terminate
    rays early.  ``gradient`` ``None`` means the
    machine's gradient source (its ``[formats] gradient.source``), or ``voxel`` for the
    ideal renderer without one.  ``iso_value`` ``None`` means the middle
    of the volume's value range.
    """

    mode: str = "composite"
    lighting: bool = True
    interpolation: str = "trilinear"
    gradient: str | None = None
    sample_spacing: float = 1.0
    supersampling: float = 1.0
    early_termination: float = 1.0
    blend_order: str = "front-to-back"
    iso_value: float | None = None
    iso_color: tuple[float, float, float] = (0.9, 0.85, 0.75)

    @property
    def step(self) -> float:
        """Distance between samples along a ray, in smallest-voxel-spacing units."""
        return self.sample_spacing / self.supersampling


@dataclass(frozen=True, kw_only=True)
class CropSpec:
    """Three axis slabs (voxel index coordinates, inclusive; ``None``: no limit, the axis
    is always inside) combined as VolumePro's cropping does: ``subvolume`` keeps samples
    inside all three slabs, ``cross`` inside at least two, ``fence`` inside at least one;
    ``invert`` keeps the complement."""

    x: tuple[float, float] | None = None
    y: tuple[float, float] | None = None
    z: tuple[float, float] | None = None
    invert: bool = False
    mode: str = "subvolume"

    @property
    def slabs_needed(self) -> int:
        """How many of the three slabs a kept sample lies in (before ``invert``)."""
        return CROP_MODES[self.mode]


@dataclass(frozen=True, kw_only=True)
class CutPlane:
    """A thick cut plane: ``normal . p = offset`` (world units, ``p`` relative to the volume
    centre, ``normal`` in ``(x, y, z)``).  Samples within ``thickness/2`` of the plane are
    kept (removed with ``invert``); opacity falls off linearly over ``falloff`` beyond."""

    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset: float = 0.0
    thickness: float = 0.0
    falloff: float = 0.0
    invert: bool = False


@dataclass(frozen=True, kw_only=True)
class Scene:
    """A complete, validated scene.  Derive variants with :meth:`replace`."""

    name: str = "scene"
    source: str = "<built-in>"
    volume: VolumeSpec = field(default_factory=lambda: VolumeSpec(phantom="head"))
    transfer: TransferSpec = field(default_factory=TransferSpec)
    view: ViewSpec = field(default_factory=ViewSpec)
    lights: tuple[Light, ...] = (Light(),)
    material: Material = field(default_factory=Material)
    render: RenderSpec = field(default_factory=RenderSpec)
    crop: CropSpec | None = None
    cut_planes: tuple[CutPlane, ...] = ()
    classification: ClassificationSpec | None = None
    geometry: GeometrySpec | None = None
    cursor: CursorSpec | None = None

    @property
    def base_dir(self) -> Path:
        """Folder relative volume paths are resolved against."""
        src = Path(self.source)
        return src.parent if src.suffix == ".toml" else Path.cwd()

    @property
    def lit(self) -> bool:
        """Whether shading (and so a gradient) is needed."""
        return self.render.mode in ("composite", "iso") and self.render.lighting

    def replace(self, **sections: Any) -> Scene:
        return dataclasses.replace(self, **sections)

    def to_dict(self) -> dict[str, Any]:
        """The resolved scene as plain data (for stats.json)."""
        out = dataclasses.asdict(self)
        volume = out["volume"]
        volume["params"] = dict(self.volume.params)
        # Only the keys that describe this kind of volume, so the dict parses back.
        unused = ("shape", "dtype", "byte_order", "header_bytes") if self.volume.phantom else ()
        for key in (*unused, *(("params",) if self.volume.path else ())):
            volume.pop(key)
        out["transfer"].pop("chosen_by")  # stats.json's "transfer" says it; the dict parses back
        if out.get("classification"):  # as the file has it: the LUTs hold the functions
            for key in ("preset", "points", "table", "table_range"):
                out["transfer"].pop(key)
            out["classification"]["luts"] = [
                {"field": lut["field"], "entries": lut["entries"], **(lut["transfer"] or {})}
                for lut in out["classification"]["luts"]
            ]
            for lut in out["classification"]["luts"]:  # [transfer] holds these
                for key in ("chosen_by", "order", "gradient_opacity"):
                    lut.pop(key, None)
            alus = ("leaf0", "leaf1", "final")
            out["classification"]["combine"] = {k: out["classification"].pop(k) for k in alus}
        out["schema"] = SCHEMA
        return out


# --------------------------------------------------------------------------- parsing


def builtin_scenes() -> dict[str, str]:
    """Built-in scene names and their one-line descriptions."""
    out = {}
    for item in sorted(resources.files("hwsim.scenes").iterdir(), key=lambda p: p.name):
        if item.name.endswith(".toml"):
            data = read_toml(Path(str(item)))
            out[item.name[:-5]] = str(data.get("description", ""))
    return out


def load_scene(name_or_path: str | Path | None = None) -> Scene:
    """Load a scene from a TOML file or by built-in name (default: ``DEFAULT_SCENE``)."""
    if name_or_path is None:
        name_or_path = DEFAULT_SCENE
    text = str(name_or_path)
    if not text.endswith(".toml") and "/" not in text:
        item = resources.files("hwsim.scenes") / f"{text}.toml"
        if not item.is_file():
            raise InputError(
                f"unknown built-in scene {text!r}", key="scene", allowed=", ".join(builtin_scenes())
            )
        return parse_scene(read_toml(Path(str(item))), source=f"<built-in {text}>", name=text)
    path = Path(text)
    return parse_scene(read_toml(path), source=str(path), name=path.stem)


def parse_scene(data: dict[str, Any], *, source: str = "<scene>", name: str = "scene") -> Scene:
    """Validate parsed TOML (against :class:`~hwsim.spec.scene_schema.SceneFile`) into a
    :class:`Scene`."""
    m = validate(data, SceneFile, source)
    lights = (
        (Light(),)
        if m.lights is UNSET
        else tuple(_light(x, source, i) for i, x in enumerate(m.lights))
    )
    classification = None
    if m.classification is not UNSET:
        _transfer_beside_luts(m.transfer, source)
        classification = parse_classification(m.classification, source, _transfer_spec)
    return Scene(
        name=name if m.name is UNSET else m.name,
        source=source,
        volume=_volume(m.volume, source),
        transfer=_transfer_spec(m.transfer, source, "transfer"),
        view=ViewSpec(**given(m.view)),
        lights=lights,
        material=Material(**given(m.material)),
        render=_render(m.render, source),
        crop=None if m.crop is UNSET else _crop(m.crop, source),
        cut_planes=tuple(_cut_plane(p, source, i) for i, p in enumerate(m.cut_planes)),
        classification=classification,
        geometry=None if m.geometry is UNSET else parse_geometry(m.geometry, source),
        cursor=None if m.cursor is UNSET else parse_cursor(m.cursor),
    )


def load_transfer(path: str | Path) -> TransferSpec:
    """A transfer-function file (``--transfer FILE.toml``): TOML holding the keys of a
    scene's ``[transfer]`` table at its top level, plus ``schema = 1`` and an optional
    ``description`` (:class:`~hwsim.spec.scene_schema.TransferFile`).  A relative
    ``table`` path is resolved against the file's folder."""
    path = Path(path)
    spec = _transfer_spec(validate(read_toml(path), TransferFile, str(path)), str(path), "")
    if spec.table is not None and not Path(spec.table).is_absolute():
        spec = dataclasses.replace(spec, table=str((path.parent / spec.table).resolve()))
    return spec


def _key(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _ascending(rows: list, source: str, key: str, what: str) -> tuple[tuple[float, ...], ...]:
    """``rows`` as tuples; their first column must not decrease."""
    for i in range(1, len(rows)):
        if rows[i][0] < rows[i - 1][0]:
            raise InputError(
                f"{what} must be ascending",
                source=source,
                key=f"{key}[{i}][0]",
                allowed=f">= {rows[i - 1][0]:g}",
            )
    return tuple(tuple(r) for r in rows)


def _transfer_spec(m: TransferModel, source: str, prefix: str) -> TransferSpec:
    """A :class:`TransferSpec` from a validated ``[transfer]`` table (also a LUT's function
    and a ``--transfer`` file's); ``prefix`` is the table's key path."""
    sources = [k for k in ("points", "table", "preset") if getattr(m, k) is not UNSET]
    if len(sources) > 1:
        raise InputError(
            f"give only one of transfer.{', transfer.'.join(sources)}",
            source=source,
            key=_key(prefix, sources[1]),
            allowed="points, table or preset",
        )
    if m.table_range is not UNSET and not m.table_range[1] > m.table_range[0]:
        raise InputError(
            "upper end must exceed lower end",
            source=source,
            key=_key(prefix, "table_range"),
            allowed="[lo, hi] with hi > lo",
        )
    out: dict[str, Any] = {"order": m.order} if m.order is not UNSET else {}
    for name in ("gradient_opacity", "gradient_illumination"):
        rows = getattr(m, name)
        if rows is not UNSET:
            out[name] = _ascending(rows, source, _key(prefix, name), "magnitudes")
    if m.points is not UNSET:
        out.update(
            preset=None, points=_ascending(m.points, source, _key(prefix, "points"), "values")
        )
    elif m.table is not UNSET:
        out.update(preset=None, table=m.table)
    elif m.preset is not UNSET:
        out["preset"] = m.preset
    if m.table_range is not UNSET:
        out["table_range"] = m.table_range
    return TransferSpec(**out)


def _transfer_beside_luts(m: TransferModel, source: str) -> None:
    """``[classification]`` LUTs replace ``[transfer]``'s RGBA function."""
    for key in ("points", "table", "preset"):
        if getattr(m, key) is not UNSET:
            raise InputError(
                "[classification] LUTs replace the transfer function",
                source=source,
                key=f"transfer.{key}",
                allowed="transfer.gradient_opacity, gradient_illumination and order only",
            )


def _volume(m: Any, source: str) -> VolumeSpec:
    kw = given(m)
    if not kw:  # no [volume] table: the default phantom
        return VolumeSpec(phantom="head")

    def error(key: str, message: str, allowed: str) -> InputError:
        return InputError(message, source=source, key=f"volume.{key}", allowed=allowed)

    if ("path" in kw) == ("phantom" in kw):
        raise error(
            "path",
            "give exactly one of volume.path or volume.phantom",
            'path = "file" or phantom = "ball"',
        )
    if "phantom" in kw:
        for key in ("shape", "dtype", "byte_order", "header_bytes"):
            if key in kw:
                raise error(
                    key,
                    "describes a .raw file, not a phantom",
                    "phantom size goes in volume.params, e.g. params = { size = 64 }",
                )
    elif "params" in kw:
        raise error("params", "phantom parameters need volume.phantom", "remove it")
    kw["params"] = tuple(sorted(kw.get("params", {}).items()))
    return VolumeSpec(**kw)


def _nonzero(vector: tuple[float, ...], source: str, key: str) -> None:
    if not any(vector):
        raise InputError(
            "must not be the zero vector", source=source, key=key, allowed="any non-zero [x, y, z]"
        )


def _light(m: Any, source: str, i: int) -> Light:
    light = Light(**given(m))
    _nonzero(light.direction, source, f"lights[{i}].direction")
    return light


def _cut_plane(m: Any, source: str, i: int) -> CutPlane:
    plane = CutPlane(**given(m))
    _nonzero(plane.normal, source, f"cut_planes[{i}].normal")
    return plane


def _render(m: Any, source: str) -> RenderSpec:
    spec = RenderSpec(**given(m))
    if spec.blend_order != RenderSpec.blend_order:
        if spec.mode != "composite":
            raise InputError(
                f"{spec.mode} has no blending order",
                source=source,
                key="render.blend_order",
                allowed='mode = "composite" (or omit blend_order)',
            )
        if spec.early_termination < 1.0:
            raise InputError(
                f"{spec.early_termination:g}: a back-to-front ray ends at its front",
                source=source,
                key="render.early_termination",
                allowed="1 (off) with blend_order = back-to-front",
            )
    return spec


def _crop(m: Any, source: str) -> CropSpec:
    crop = CropSpec(**given(m))
    for axis in ("x", "y", "z"):
        limits = getattr(crop, axis)
        if limits is not None and limits[1] < limits[0]:
            raise InputError(
                f"[{limits[0]:g}, {limits[1]:g}] is empty",
                source=source,
                key=f"crop.{axis}",
                allowed="[lo, hi] with lo <= hi",
            )
    return crop
