"""Scene sections for VolumePro 1000 datapath features: multi-LUT classification with
combiners (``[classification]``) and embedded opaque geometry (``[geometry]``).

# Ref: architectures.md section 4 (vli.h: up to 4 LUTs of 4096 or 256 entries, 3
#      combination ALUs, only one leaf may use a 4096-entry LUT; up to 4 voxel fields of
#      4..16 bits; image + 24-bit depth buffers with depth tests <, <=, =, >=, >, !=).

Both sections are optional; a scene without them renders exactly as before.  Whether a
machine has the feature is checked where the machine is known (``models.backend``).
The format is documented in ``docs/scenes.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from hwsim.core.config import Table
from hwsim.core.errors import InputError

if TYPE_CHECKING:
    from hwsim.spec.scene import TransferSpec

__all__ = [
    "VoxelField",
    "LutSpec",
    "AluSpec",
    "ClassificationSpec",
    "Sphere",
    "Box",
    "GeometrySpec",
    "DEPTH_TESTS",
    "LEAF_OPCODES",
    "FINAL_ONLY",
    "OPCODES",
    "LUT_ENTRIES",
    "MAX_LUTS",
    "MAX_FIELDS",
    "parse_classification",
    "parse_geometry",
    "check_features",
    "check_machine",
]

LUT_ENTRIES = (256, 4096)
MAX_LUTS = 4
MAX_FIELDS = 4
FIELD_BITS = (4, 16)
#: Depth tests of the embedded-geometry buffer (vli.h's six comparisons).
DEPTH_TESTS = ("<", "<=", "==", ">=", ">", "!=")
#: Combiner opcodes (semantics: ``models.units.combine``); FINAL_ONLY ones only in the
#: final ALU.
LEAF_OPCODES = (
    "a",
    "b",
    "and",
    "or",
    "xor",
    "add",
    "sub",
    "rsub",
    "min",
    "max",
    "mul",
    "mul2",
    "mul4",
    "mul8",
)
FINAL_ONLY = ("mul_b_alpha",)
OPCODES = LEAF_OPCODES + FINAL_ONLY
#: The implicit field: the whole voxel, in the volume's own units.
VALUE_FIELD = "value"


@dataclass(frozen=True, kw_only=True)
class VoxelField:
    """Bits ``lsb .. lsb + bits - 1`` of the stored (unsigned integer) voxel."""

    name: str
    lsb: int
    bits: int


@dataclass(frozen=True, kw_only=True)
class LutSpec:
    """One lookup table: the field that indexes it, its size and its transfer function
    (a :class:`~hwsim.spec.scene.TransferSpec`; values in the volume's units for the
    ``value`` field, in field integers ``0 .. 2**bits - 1`` for a declared field)."""

    field: str = VALUE_FIELD
    entries: int = 4096
    transfer: TransferSpec | None = None


@dataclass(frozen=True, kw_only=True)
class AluSpec:
    """One combination ALU: an opcode for the colour channels and one for alpha."""

    rgb: str = "a"
    alpha: str = "a"

    @property
    def ops(self) -> tuple[str, str]:
        return (self.rgb, self.alpha)


@dataclass(frozen=True, kw_only=True)
class ClassificationSpec:
    """Up to four LUTs merged by ``leaf0(lut0, lut1)``, ``leaf1(lut2, lut3)`` and
    ``final(leaf0, leaf1)``."""

    fields: tuple[VoxelField, ...] = ()
    #: The declared field the value path reads (samples, gradients), as VLI's
    #: SetGradientSource names one: required for 32-bit voxels; None: the whole voxel.
    value_field: str | None = None
    luts: tuple[LutSpec, ...] = ()
    leaf0: AluSpec = AluSpec()
    leaf1: AluSpec = AluSpec()
    final: AluSpec = AluSpec()

    def field(self, name: str) -> VoxelField | None:
        """The declared field ``name`` (None for the implicit ``value`` field)."""
        for f in self.fields:
            if f.name == name:
                return f
        return None


@dataclass(frozen=True, kw_only=True)
class Sphere:
    """An opaque sphere: ``center`` (x, y, z) in world units from the volume centre."""

    center: tuple[float, float, float]
    radius: float
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True, kw_only=True)
class Box:
    """An opaque axis-aligned box between world corners ``lo`` and ``hi`` (x, y, z)."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True, kw_only=True)
class GeometrySpec:
    """Opaque geometry rasterised (on the host) into a colour image and a depth buffer.

    Either primitives (``spheres``, ``boxes``) or a user's ``color`` / ``depth`` ``.npy``
    pair (``(H, W, 3|4)`` in 0..1 and ``(H, W)`` normalised depth in 0..1, 1 = far).
    Samples are kept where ``sample_depth <depth_test> geometry_depth``.
    """

    depth_test: str = "<"
    spheres: tuple[Sphere, ...] = ()
    boxes: tuple[Box, ...] = ()
    color: str | None = None
    depth: str | None = None


# --------------------------------------------------------------------------- parsing


def _alu(t: Table, name: str, allowed: tuple[str, ...]) -> AluSpec:
    value = t.raw(name)
    if isinstance(value, str):
        rgb = alpha = value
    elif isinstance(value, dict):
        sub = Table(value, t.source, t.key(name))
        rgb, alpha = sub.string("rgb", "a"), sub.string("alpha", "a")
        sub.finish()
    else:
        raise t.error(name, f"must be an opcode or {{rgb = ..., alpha = ...}}, got {value!r}")
    for channel, op in (("rgb", rgb), ("alpha", alpha)):
        if op not in allowed:
            key = name if isinstance(value, str) else f"{name}.{channel}"
            raise t.error(key, f"unknown or misplaced opcode {op!r}", ", ".join(allowed))
    return AluSpec(rgb=rgb, alpha=alpha)


def parse_classification(t: Table, parse_transfer) -> ClassificationSpec:
    """Validate a ``[classification]`` table (``parse_transfer``: the scene's
    ``[transfer]`` parser, reused for each LUT's function)."""
    fields = []
    for f in t.tables("fields"):
        name = f.string("name")
        if name == VALUE_FIELD or any(g.name == name for g in fields):
            raise f.error("name", f"duplicate or reserved field name {name!r}", "a new name")
        bits = f.integer("bits", lo=FIELD_BITS[0], hi=FIELD_BITS[1])
        lsb = f.integer("lsb", 0, 0, 32 - bits)
        fields.append(VoxelField(name=name, lsb=lsb, bits=bits))
        f.finish()
    if len(fields) > MAX_FIELDS:
        raise t.error("fields", f"{len(fields)} fields", f"1 .. {MAX_FIELDS}")
    names = [VALUE_FIELD] + [f.name for f in fields]
    value_field = t.choice("value_field", names[1:]) if t.has("value_field") else None
    luts = []
    for lt in t.tables("luts"):
        field = lt.choice("field", names, VALUE_FIELD)
        entries = lt.integer("entries", 4096)
        if entries not in LUT_ENTRIES:
            raise lt.error("entries", f"{entries} entries", "256, 4096")
        for key in ("gradient_opacity", "order"):
            if lt.has(key):
                raise lt.error(key, "set it in [transfer] (it applies to the combined output)")
        rest = {k: v for k, v in lt.data.items() if k not in ("field", "entries")}
        if field != VALUE_FIELD and "points" not in rest and "table_range" not in rest:
            raise lt.error(
                "points",
                f"a LUT on field {field!r} needs its function in field integers",
                "points, or table with table_range",
            )
        tf = parse_transfer(Table(rest, t.source, lt.path))
        luts.append(LutSpec(field=field, entries=entries, transfer=tf))
    if not 1 <= len(luts) <= MAX_LUTS:
        raise t.error("luts", f"{len(luts)} LUTs", f"1 .. {MAX_LUTS} [[classification.luts]]")
    big = [i // 2 for i, lut in enumerate(luts) if lut.entries == 4096]
    if len(set(big)) > 1:
        raise t.error(
            "luts",
            "4096-entry LUTs feed both leaf ALUs",
            "4096 entries on lut0/lut1 or on lut2/lut3 only, 256 on the other leaf",
        )
    c = t.table("combine")
    n = len(luts)
    needed = {"leaf0": n >= 2, "leaf1": n >= 4, "final": n >= 3}
    alus = {}
    for name, must in needed.items():
        if c.has(name):
            alus[name] = _alu(c, name, OPCODES if name == "final" else LEAF_OPCODES)
        elif must:
            raise c.error(name, f"is required with {n} LUTs", ", ".join(OPCODES))
        else:
            alus[name] = AluSpec()
    c.finish()
    t.finish()
    return ClassificationSpec(
        fields=tuple(fields), value_field=value_field, luts=tuple(luts), **alus
    )


def _sphere(t: Table) -> Sphere:
    s = Sphere(
        center=t.vector("center", 3),  # type: ignore[arg-type]
        radius=t.number("radius", lo=0, lo_open=True),
        color=t.vector("color", 3, (1.0, 1.0, 1.0), 0, 1),  # type: ignore[arg-type]
    )
    t.finish()
    return s


def _box(t: Table) -> Box:
    lo, hi = t.vector("lo", 3), t.vector("hi", 3)
    for i in range(3):
        if not hi[i] > lo[i]:
            raise t.error(f"hi[{i}]", f"{hi[i]:g} must exceed lo[{i}] = {lo[i]:g}", f"> {lo[i]:g}")
    b = Box(lo=lo, hi=hi, color=t.vector("color", 3, (1.0, 1.0, 1.0), 0, 1))  # type: ignore[arg-type]
    t.finish()
    return b


def parse_geometry(t: Table) -> GeometrySpec:
    """Validate a ``[geometry]`` table."""
    spec = GeometrySpec(
        depth_test=t.choice("depth_test", DEPTH_TESTS, "<"),
        spheres=tuple(_sphere(s) for s in t.tables("spheres")),
        boxes=tuple(_box(b) for b in t.tables("boxes")),
        color=t.string("color") if t.has("color") else None,
        depth=t.string("depth") if t.has("depth") else None,
    )
    if (spec.color is None) != (spec.depth is None):
        missing = "depth" if spec.depth is None else "color"
        raise t.error(missing, "give both geometry.color and geometry.depth", "two .npy files")
    if spec.color is not None and (spec.spheres or spec.boxes):
        raise t.error("color", "give primitives or a color/depth pair, not both")
    if spec.color is None and not (spec.spheres or spec.boxes):
        raise t.error(
            "spheres", "no geometry", "[[geometry.spheres]], [[geometry.boxes]] or color/depth"
        )
    t.finish()
    return spec


def check_features(scene) -> None:
    """Refuse feature use the render mode cannot honour (all need composite mode)."""
    sections = (
        ("classification", scene.classification),
        ("geometry", scene.geometry),
        ("cursor", scene.cursor),
    )
    for key, spec in sections:
        if spec is not None and scene.render.mode != "composite":
            raise InputError(
                f"[{key}] needs composite mode, not {scene.render.mode!r}",
                source=scene.source,
                key="render.mode",
                allowed="composite",
            )


def check_machine(scene, arch) -> None:
    """Refuse the features ``arch`` (an :class:`~hwsim.spec.arch.ArchConfig`) does not have:
    more LUTs than ``[features] classification_luts``, geometry without
    ``embedded_geometry``.  Also checks the render mode (:func:`check_features`)."""
    check_features(scene)
    if scene.classification is not None:
        n = len(scene.classification.luts)
        if n > arch.classification_luts:
            raise InputError(
                f"{arch.name} has {arch.classification_luts} classification LUT(s), "
                f"the scene uses {n}",
                source=arch.source,
                key="features.classification_luts",
                allowed=f"1 .. {arch.classification_luts} [[classification.luts]]",
            )
    if scene.geometry is not None and not arch.embedded_geometry:
        raise InputError(
            f"{arch.name} has no embedded-geometry depth buffer",
            source=arch.source,
            key="features.embedded_geometry",
            allowed="a machine with embedded_geometry = true (volumepro1000)",
        )
