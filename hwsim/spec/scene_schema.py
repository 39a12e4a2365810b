"""The scene file's schema: every key a scene (and a ``--transfer`` file) may hold, its type,
range and choices, declared once as msgspec models (:mod:`hwsim.core.models`).

A key the file leaves out is ``UNSET`` here and takes the default of the dataclass it
builds (:mod:`hwsim.spec.scene`, :mod:`hwsim.spec.scene_features`,
:mod:`hwsim.spec.scene_cursor`), so defaults have one home too.  Rules a type cannot say
(exactly one volume source, ascending control points, ``lo <= hi``, a LUT's field among the
declared ones) are checked by the builders after validation, each one line naming the
file and key.  The format is documented in ``docs/scenes.md``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from msgspec import UNSET, Meta, UnsetType

from hwsim.core.models import Finite, Schema, between, count, finite_at_least, integer

__all__ = [
    "SCHEMA",
    "MODES",
    "BLEND_ORDERS",
    "PROJECTIONS",
    "INTERPOLATIONS",
    "GRADIENT_SOURCES",
    "CLASSIFICATION_ORDERS",
    "TF_PRESETS",
    "CROP_MODES",
    "MAX_IMAGE",
    "MAX_SHAPE",
    "LUT_ENTRIES",
    "MAX_LUTS",
    "MAX_FIELDS",
    "FIELD_BITS",
    "DEPTH_TESTS",
    "LEAF_OPCODES",
    "FINAL_ONLY",
    "OPCODES",
    "CURSOR_TYPES",
    "CURSOR_WIDTHS",
    "SceneFile",
    "TransferFile",
    "TransferModel",
    "VolumeModel",
    "ViewModel",
    "RenderModel",
    "given",
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
#: Crop mode -> slabs a sample must lie in (VTK's region flags: SUBVOLUME, CROSS, FENCE).
CROP_MODES = {"subvolume": 3, "cross": 2, "fence": 1}
#: Largest image side.  Whether a large image fits is the memory budget's call
#: (hwsim.run.fidelity.check_work: about 512 bytes per pixel, 4096^2 needs 8 GiB).
MAX_IMAGE = 4096
#: Largest side of a headerless ``.raw`` volume (``volume.shape``, ``--shape``).
MAX_SHAPE = 1 << 16

# Ref: architectures.md section 4 (vli.h: up to 4 LUTs of 4096 or 256 entries, 3
#      combination ALUs, up to 4 voxel fields of 4..16 bits, depth tests <, <=, =, >=, >, !=).
LUT_ENTRIES = (256, 4096)
MAX_LUTS = 4
MAX_FIELDS = 4
FIELD_BITS = (4, 16)
#: Depth tests of the embedded-geometry buffer (vli.h's six comparisons).
DEPTH_TESTS = ("<", "<=", "==", ">=", ">", "!=")
#: Combiner opcodes (semantics: ``models.units.combine``); FINAL_ONLY ones only in the
#: final ALU.
LEAF_OPCODES = (
    "a", "b", "and", "or", "xor", "add", "sub", "rsub", "min", "max", "mul", "mul2", "mul4",
    "mul8",
)  # fmt: skip
FINAL_ONLY = ("mul_b_alpha",)
OPCODES = LEAF_OPCODES + FINAL_ONLY
CURSOR_TYPES = ("crosshair", "plane")
#: vli.h SetWidth: "width (1.0, 3.0, 5.0 or 7.0)".
CURSOR_WIDTHS = (1, 3, 5, 7)

Unit = between(0, 1)
Vec3 = tuple[Finite, Finite, Finite]
Colour = tuple[Unit, Unit, Unit]
#: ``[value, r, g, b, alpha]`` control points (values ascending: checked by the builder).
Points = Annotated[list[tuple[Finite, Unit, Unit, Unit, Unit]], Meta(min_length=1)]
#: ``[|gradient|, factor]`` rows (magnitudes ascending: checked by the builder).
MagnitudeRows = Annotated[list[tuple[finite_at_least(0), Unit]], Meta(min_length=1)]


def given(model: Schema) -> dict[str, Any]:
    """The fields of ``model`` the file gave (not ``UNSET``): keywords for a dataclass
    whose own defaults fill the rest."""
    return {k: v for k in model.__struct_fields__ if (v := getattr(model, k)) is not UNSET}


class VolumeModel(Schema):
    path: str | UnsetType = UNSET
    phantom: str | UnsetType = UNSET
    params: dict[str, Any] | UnsetType = UNSET
    shape: tuple[count(MAX_SHAPE), count(MAX_SHAPE), count(MAX_SHAPE)] | UnsetType = UNSET
    dtype: str | UnsetType = UNSET
    byte_order: Literal["little", "big"] | UnsetType = UNSET
    header_bytes: integer(0) | UnsetType = UNSET
    spacing: tuple[between(1e-6, 1e6), between(1e-6, 1e6), between(1e-6, 1e6)] | UnsetType = UNSET


class TransferModel(Schema):
    """A ``[transfer]`` table: one of points, table or preset, plus modulation."""

    points: Points | UnsetType = UNSET
    table: str | UnsetType = UNSET
    table_range: tuple[Finite, Finite] | UnsetType = UNSET
    preset: Literal[TF_PRESETS] | UnsetType = UNSET
    gradient_opacity: MagnitudeRows | UnsetType = UNSET
    order: Literal[CLASSIFICATION_ORDERS] | UnsetType = UNSET
    gradient_illumination: MagnitudeRows | UnsetType = UNSET


class TransferFile(TransferModel):
    """A ``--transfer FILE.toml``: a ``[transfer]`` table at the top level."""

    schema: Literal[SCHEMA] = SCHEMA
    description: str = ""


class ViewModel(Schema):
    azimuth: between(-360, 360) | UnsetType = UNSET
    elevation: between(-90, 90) | UnsetType = UNSET
    projection: Literal[PROJECTIONS] | UnsetType = UNSET
    fov: between(1, 170) | UnsetType = UNSET
    distance: between(1, 1000, open_lo=True) | UnsetType = UNSET
    zoom: between(0.01, 100) | UnsetType = UNSET
    width: integer(1, MAX_IMAGE) | UnsetType = UNSET
    height: integer(1, MAX_IMAGE) | UnsetType = UNSET


class LightModel(Schema):
    direction: Vec3 | UnsetType = UNSET  # not the zero vector: checked by the builder
    intensity: between(0, 100) | UnsetType = UNSET
    space: Literal["view", "world"] | UnsetType = UNSET


class MaterialModel(Schema):
    ambient: Unit | UnsetType = UNSET
    diffuse: Unit | UnsetType = UNSET
    specular: Unit | UnsetType = UNSET
    shininess: between(1, 1024) | UnsetType = UNSET


class RenderModel(Schema):
    mode: Literal[MODES] | UnsetType = UNSET
    lighting: bool | UnsetType = UNSET
    interpolation: Literal[INTERPOLATIONS] | UnsetType = UNSET
    gradient: Literal[GRADIENT_SOURCES] | UnsetType = UNSET
    sample_spacing: between(0.0625, 16) | UnsetType = UNSET
    supersampling: between(0.125, 16) | UnsetType = UNSET
    early_termination: between(0, 1, open_lo=True) | UnsetType = UNSET
    blend_order: Literal[BLEND_ORDERS] | UnsetType = UNSET
    iso_value: Finite | UnsetType = UNSET
    iso_color: Colour | UnsetType = UNSET


class CropModel(Schema):
    x: tuple[Finite, Finite] | UnsetType = UNSET  # lo <= hi: checked by the builder
    y: tuple[Finite, Finite] | UnsetType = UNSET
    z: tuple[Finite, Finite] | UnsetType = UNSET
    invert: bool | UnsetType = UNSET
    mode: Literal[tuple(CROP_MODES)] | UnsetType = UNSET


class CutPlaneModel(Schema):
    normal: Vec3 | UnsetType = UNSET  # not the zero vector: checked by the builder
    offset: Finite | UnsetType = UNSET
    thickness: finite_at_least(0) | UnsetType = UNSET
    falloff: finite_at_least(0) | UnsetType = UNSET
    invert: bool | UnsetType = UNSET


class FieldModel(Schema):
    name: str
    bits: integer(*FIELD_BITS)
    lsb: integer(0, 32 - FIELD_BITS[0]) | UnsetType = UNSET  # <= 32 - bits: the builder


class LutModel(TransferModel):
    """One ``[[classification.luts]]``: the keys of ``[transfer]`` plus its index field."""

    field: str | UnsetType = UNSET  # a declared field or "value": checked by the builder
    entries: Literal[LUT_ENTRIES] | UnsetType = UNSET


class LeafAlu(Schema):
    rgb: Literal[LEAF_OPCODES] = "a"
    alpha: Literal[LEAF_OPCODES] = "a"


class FinalAlu(Schema):
    rgb: Literal[OPCODES] = "a"
    alpha: Literal[OPCODES] = "a"


class CombineModel(Schema):
    """An opcode for every channel, or ``{rgb = .., alpha = ..}``; required ones: builder."""

    leaf0: Literal[LEAF_OPCODES] | LeafAlu | UnsetType = UNSET
    leaf1: Literal[LEAF_OPCODES] | LeafAlu | UnsetType = UNSET
    final: Literal[OPCODES] | FinalAlu | UnsetType = UNSET


class ClassificationModel(Schema):
    luts: Annotated[list[LutModel], Meta(min_length=1, max_length=MAX_LUTS)]
    fields: Annotated[list[FieldModel], Meta(max_length=MAX_FIELDS)] = []
    value_field: str | UnsetType = UNSET
    combine: CombineModel = CombineModel()


class SphereModel(Schema):
    center: Vec3
    radius: finite_at_least(0, open_lo=True)
    color: Colour | UnsetType = UNSET


class BoxModel(Schema):
    lo: Vec3
    hi: Vec3  # > lo on every axis: checked by the builder
    color: Colour | UnsetType = UNSET


class GeometryModel(Schema):
    depth_test: Literal[DEPTH_TESTS] | UnsetType = UNSET
    spheres: list[SphereModel] = []
    boxes: list[BoxModel] = []
    color: str | UnsetType = UNSET
    depth: str | UnsetType = UNSET


class CursorAxisModel(Schema):
    color: Colour | UnsetType = UNSET
    opacity: Unit | UnsetType = UNSET
    enabled: bool | UnsetType = UNSET


class CursorModel(Schema):
    position: tuple[between(-1e6, 1e6), between(-1e6, 1e6), between(-1e6, 1e6)]
    type: Literal[CURSOR_TYPES] | UnsetType = UNSET
    width: Literal[CURSOR_WIDTHS] | UnsetType = UNSET
    length: between(0, 1e6) | UnsetType = UNSET
    exclude_overlap: bool | UnsetType = UNSET
    disable_crop: bool | UnsetType = UNSET
    x: CursorAxisModel = CursorAxisModel()
    y: CursorAxisModel = CursorAxisModel()
    z: CursorAxisModel = CursorAxisModel()


class SceneFile(Schema):
    """A scene file (``hwsim render SCENE``, ``hwsim/scenes/*.toml``)."""

    schema: Literal[SCHEMA] = SCHEMA
    name: str | UnsetType = UNSET
    description: str = ""
    volume: VolumeModel = VolumeModel()
    transfer: TransferModel = TransferModel()
    view: ViewModel = ViewModel()
    lights: list[LightModel] | UnsetType = UNSET
    material: MaterialModel = MaterialModel()
    render: RenderModel = RenderModel()
    crop: CropModel | UnsetType = UNSET
    cut_planes: list[CutPlaneModel] = []
    classification: ClassificationModel | UnsetType = UNSET
    geometry: GeometryModel | UnsetType = UNSET
    cursor: CursorModel | UnsetType = UNSET
