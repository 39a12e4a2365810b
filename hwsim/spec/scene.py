"""Scene = volume + transfer function + view + lights + material + render mode.

A scene is versioned TOML (``schema = 1``) read into frozen dataclasses; every value is
validated and a bad one raises :class:`hwsim.core.errors.InputError` naming the file, the
key path and the allowed range.  The format is documented in ``docs/scenes.md``.

Vectors a user writes are in ``(x, y, z)`` order (light directions, cut-plane normals);
arrays are ``(z, y, x)``.  Crop limits are named per axis (``crop.x = [lo, hi]``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from hwsim.core.config import Table, check_points, read_toml
from hwsim.core.errors import InputError
from hwsim.spec.scene_cursor import CursorSpec, parse_cursor
from hwsim.spec.scene_features import (
    ClassificationSpec,
    GeometrySpec,
    parse_classification,
    parse_geometry,
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
]

SCHEMA = 1
MODES = ("composite", "mip", "minip", "xray", "iso")
#: Compositing orders (VLI's kVLIBlendFTB / kVLIBlendBTF): the order samples are blended.
BLEND_ORDERS = ("front-to-back", "back-to-front")
PROJECTIONS = ("parallel", "perspective")
INTERPOLATIONS = ("trilinear", "nearest", "cubic")
GRADIENT_SOURCES = ("voxel", "sample")
CLASSIFICATION_ORDERS = ("post", "pre")
#: Transfer presets (hwsim.spec.transfer.preset_points); ``auto`` chooses one of the others
#: from the volume (hwsim.spec.preset_choice).
TF_PRESETS = ("auto", "ct", "mr", "ramp", "warm")
DEFAULT_SCENE = "head"
#: Largest image side.  Whether a large image fits is the memory budget's call
#: (hwsim.run.fidelity.check_work: about 512 bytes per pixel, 4096^2 needs 8 GiB).
MAX_IMAGE = 4096


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


#: Crop mode -> slabs a sample must lie in (VTK's region flags: SUBVOLUME, CROSS, FENCE).
CROP_MODES = {"subvolume": 3, "cross": 2, "fence": 1}


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
        for lut in (out.get("classification") or {}).get("luts", ()):
            if lut.get("transfer"):
                lut["transfer"].pop("chosen_by")
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
    """Validate parsed TOML into a :class:`Scene`."""
    top = Table(data, source)
    top.schema(SCHEMA)
    top.string("description", "")
    scene = Scene(
        name=top.string("name", name),
        source=source,
        volume=_volume(top.table("volume")),
        transfer=_transfer(top.table("transfer")),
        view=_view(top.table("view")),
        lights=tuple(_light(t) for t in top.tables("lights")) if top.has("lights") else (Light(),),
        material=_material(top.table("material")),
        render=_render(top.table("render")),
        crop=_crop(top.table("crop")) if top.has("crop") else None,
        cut_planes=tuple(_cut_plane(t) for t in top.tables("cut_planes")),
        classification=_classification(top),
        geometry=parse_geometry(top.table("geometry")) if top.has("geometry") else None,
        cursor=parse_cursor(top.table("cursor")) if top.has("cursor") else None,
    )
    top.finish()
    return scene


def load_transfer(path: str | Path) -> TransferSpec:
    """A transfer-function file (``--transfer FILE.toml``): TOML holding the keys of a
    scene's ``[transfer]`` table at its top level, plus ``schema = 1`` and an optional
    ``description``.  A relative ``table`` path is resolved against the file's folder."""
    path = Path(path)
    data = dict(read_toml(path))
    head = Table({k: data.pop(k) for k in ("schema", "description") if k in data}, str(path))
    head.schema(SCHEMA)
    head.string("description", "")
    head.finish()
    spec = _transfer(Table(data, str(path)))
    if spec.table is not None and not Path(spec.table).is_absolute():
        spec = dataclasses.replace(spec, table=str((path.parent / spec.table).resolve()))
    return spec


def _magnitude_rows(t: Table, key: str) -> tuple[tuple[float, float], ...] | None:
    """``[|gradient|, factor]`` rows: magnitudes >= 0 ascending, factors 0..1."""
    if not t.has(key):
        return None
    rows = check_points(t.raw(key), t.source, t.key(key), 2)
    for i, row in enumerate(rows):
        if row[0] < 0 or (i and row[0] < rows[i - 1][0]):
            raise t.error(f"{key}[{i}][0]", "magnitudes must be >= 0 and ascending")
        if not 0.0 <= row[1] <= 1.0:
            raise t.error(f"{key}[{i}][1]", f"{row[1]:g} is out of range", "0 .. 1")
    return tuple(tuple(r) for r in rows)  # type: ignore[misc]


def _classification(top: Table) -> ClassificationSpec | None:
    """``[classification]`` (multi-LUT); it replaces ``[transfer]``'s RGBA function."""
    if not top.has("classification"):
        return None
    transfer = top.data.get("transfer", {})
    for key in ("points", "table", "preset"):
        if isinstance(transfer, dict) and key in transfer:
            raise top.error(
                f"transfer.{key}",
                "[classification] LUTs replace the transfer function",
                "transfer.gradient_opacity, gradient_illumination and order only",
            )
    return parse_classification(top.table("classification"), _transfer)


def _volume(t: Table) -> VolumeSpec:
    if not t.data:  # no [volume] table: the default phantom
        return VolumeSpec(phantom="head")
    if t.has("path") == t.has("phantom"):
        raise t.error(
            "path",
            "give exactly one of volume.path or volume.phantom",
            'path = "file" or phantom = "ball"',
        )
    if t.has("phantom"):
        for key in ("shape", "dtype", "byte_order", "header_bytes"):
            if t.has(key):
                raise t.error(
                    key,
                    "describes a .raw file, not a phantom",
                    "phantom size goes in volume.params, e.g. params = { size = 64 }",
                )
    elif t.has("params"):
        raise t.error("params", "phantom parameters need volume.phantom", "remove it")
    params = t.table("params")
    items = tuple(sorted((k, params.raw(k)) for k in list(params.data)))
    shape = t.raw("shape", None)
    if shape is not None:
        shape = tuple(int(v) for v in t.vector("shape", 3, lo=1))
    spacing = t.vector("spacing", 3, lo=1e-6, hi=1e6) if t.has("spacing") else None
    spec = VolumeSpec(
        path=t.string("path") if t.has("path") else None,
        phantom=t.string("phantom") if t.has("phantom") else None,
        params=items,
        shape=shape,  # type: ignore[arg-type]
        dtype=t.string("dtype", None) if t.has("dtype") else None,
        byte_order=t.choice("byte_order", ("little", "big"), "little"),
        header_bytes=t.integer("header_bytes", 0, lo=0),
        spacing=spacing,  # type: ignore[arg-type]
    )
    t.finish()
    return spec


def _transfer(t: Table) -> TransferSpec:
    sources = [k for k in ("points", "table", "preset") if t.has(k)]
    if len(sources) > 1:
        raise t.error(
            sources[1],
            f"give only one of transfer.{', transfer.'.join(sources)}",
            "points, table or preset",
        )
    points = None
    if t.has("points"):
        rows = check_points(t.raw("points"), t.source, t.key("points"), 5)
        for i, row in enumerate(rows):
            for j in range(1, 5):
                if not 0.0 <= row[j] <= 1.0:
                    raise t.error(f"points[{i}][{j}]", f"{row[j]:g} is out of range", "0 .. 1")
            if i and row[0] < rows[i - 1][0]:
                raise t.error(
                    f"points[{i}][0]", "values must be ascending", f">= {rows[i - 1][0]:g}"
                )
        points = tuple(tuple(r) for r in rows)
    table_range = t.vector("table_range", 2) if t.has("table_range") else None
    if table_range is not None and not table_range[1] > table_range[0]:
        raise t.error("table_range", "upper end must exceed lower end", "[lo, hi] with hi > lo")
    spec = TransferSpec(
        preset=t.choice("preset", TF_PRESETS, "auto") if not (points or t.has("table")) else None,
        points=points,  # type: ignore[arg-type]
        table=t.string("table") if t.has("table") else None,
        table_range=table_range,  # type: ignore[arg-type]
        gradient_opacity=_magnitude_rows(t, "gradient_opacity"),  # type: ignore[arg-type]
        order=t.choice("order", CLASSIFICATION_ORDERS, "post"),
        gradient_illumination=_magnitude_rows(t, "gradient_illumination"),  # type: ignore[arg-type]
    )
    t.finish()
    return spec


def _view(t: Table) -> ViewSpec:
    d = ViewSpec()
    spec = ViewSpec(
        azimuth=t.number("azimuth", d.azimuth, -360, 360),
        elevation=t.number("elevation", d.elevation, -90, 90),
        projection=t.choice("projection", PROJECTIONS, d.projection),
        fov=t.number("fov", d.fov, 1, 170),
        distance=t.number("distance", d.distance, 1, 1000, lo_open=True),
        zoom=t.number("zoom", d.zoom, 0.01, 100),
        width=t.integer("width", d.width, 1, MAX_IMAGE),
        height=t.integer("height", d.height, 1, MAX_IMAGE),
    )
    t.finish()
    return spec


def _light(t: Table) -> Light:
    d = Light()
    direction = t.direction("direction", d.direction)
    light = Light(
        direction=direction,
        intensity=t.number("intensity", d.intensity, 0, 100),
        space=t.choice("space", ("view", "world"), d.space),
    )
    t.finish()
    return light


def _material(t: Table) -> Material:
    d = Material()
    m = Material(
        ambient=t.number("ambient", d.ambient, 0, 1),
        diffuse=t.number("diffuse", d.diffuse, 0, 1),
        specular=t.number("specular", d.specular, 0, 1),
        shininess=t.number("shininess", d.shininess, 1, 1024),
    )
    t.finish()
    return m


def _render(t: Table) -> RenderSpec:
    d = RenderSpec()
    spec = RenderSpec(
        mode=t.choice("mode", MODES, d.mode),
        lighting=t.boolean("lighting", d.lighting),
        interpolation=t.choice("interpolation", INTERPOLATIONS, d.interpolation),
        gradient=t.choice("gradient", GRADIENT_SOURCES) if t.has("gradient") else None,
        sample_spacing=t.number("sample_spacing", d.sample_spacing, 0.0625, 16),
        supersampling=t.number("supersampling", d.supersampling, 0.125, 16),
        early_termination=t.number("early_termination", d.early_termination, 0, 1, lo_open=True),
        iso_value=t.number("iso_value") if t.has("iso_value") else None,
        iso_color=t.vector("iso_color", 3, d.iso_color, 0, 1),  # type: ignore[arg-type]
        blend_order=t.choice("blend_order", BLEND_ORDERS, d.blend_order),
    )
    if spec.blend_order != d.blend_order:
        if spec.mode != "composite":
            raise t.error(
                "blend_order",
                f"{spec.mode} has no blending order",
                'mode = "composite" (or omit blend_order)',
            )
        if spec.early_termination < 1.0:
            raise t.error(
                "early_termination",
                f"{spec.early_termination:g}: a back-to-front ray ends at its front",
                "1 (off) with blend_order = back-to-front",
            )
    t.finish()
    return spec


def _crop(t: Table) -> CropSpec:
    limits = {}
    for axis in ("x", "y", "z"):
        if t.has(axis):
            lo, hi = t.vector(axis, 2)
            if hi < lo:
                raise t.error(axis, f"[{lo:g}, {hi:g}] is empty", "[lo, hi] with lo <= hi")
            limits[axis] = (lo, hi)
    crop = CropSpec(
        **limits,
        invert=t.boolean("invert", False),
        mode=t.choice("mode", CROP_MODES, "subvolume"),
    )
    t.finish()
    return crop


def _cut_plane(t: Table) -> CutPlane:
    d = CutPlane()
    normal = t.direction("normal", d.normal)
    plane = CutPlane(
        normal=normal,
        offset=t.number("offset", d.offset),
        thickness=t.number("thickness", d.thickness, 0),
        falloff=t.number("falloff", d.falloff, 0),
        invert=t.boolean("invert", d.invert),
    )
    t.finish()
    return plane
