"""Scene sections for VolumePro 1000 datapath features: multi-LUT classification with
combiners (``[classification]``) and embedded opaque geometry (``[geometry]``).

# Ref: architectures.md section 4 (vli.h: up to 4 LUTs of 4096 or 256 entries, 3
#      combination ALUs, only one leaf may use a 4096-entry LUT; up to 4 voxel fields of
#      4..16 bits; image + 24-bit depth buffers with depth tests <, <=, =, >=, >, !=).

Both sections are optional; a scene without them renders exactly as before.  Their keys'
types and ranges are the model's (:mod:`hwsim.spec.scene_schema`); the rules between keys
are checked here.  Whether a machine has the feature is checked where the machine is known
(``models.backend``).
The format is documented in ``docs/scenes.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from msgspec import UNSET

from hwsim.core.errors import InputError
from hwsim.spec.scene_schema import (
    DEPTH_TESTS,
    FINAL_ONLY,
    LEAF_OPCODES,
    LUT_ENTRIES,
    MAX_FIELDS,
    MAX_LUTS,
    OPCODES,
    ClassificationModel,
    GeometryModel,
    given,
)

if TYPE_CHECKING:
    from collections.abc import Callable

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


# --------------------------------------------------------------------------- building


def _error(key: str, message: str, source: str, allowed: str | None = None) -> InputError:
    return InputError(message, source=source, key=f"classification.{key}", allowed=allowed)


def _fields(m: ClassificationModel, source: str) -> tuple[VoxelField, ...]:
    fields: list[VoxelField] = []
    for i, f in enumerate(m.fields):
        if f.name == VALUE_FIELD or any(g.name == f.name for g in fields):
            raise _error(
                f"fields[{i}].name",
                f"duplicate or reserved field name {f.name!r}",
                source,
                "a new name",
            )
        lsb = 0 if f.lsb is UNSET else f.lsb
        if lsb > 32 - f.bits:
            raise _error(
                f"fields[{i}].lsb",
                f"bits {lsb} .. {lsb + f.bits - 1} pass bit 31",
                source,
                f"0 .. {32 - f.bits}",
            )
        fields.append(VoxelField(name=f.name, lsb=lsb, bits=f.bits))
    return tuple(fields)


def _luts(
    m: ClassificationModel, names: list[str], source: str, transfer_spec
) -> tuple[LutSpec, ...]:
    luts = []
    for i, lut in enumerate(m.luts):
        key = f"luts[{i}]"
        field = VALUE_FIELD if lut.field is UNSET else lut.field
        if field not in names:
            raise _error(f"{key}.field", f"unknown value {field!r}", source, ", ".join(names))
        for name in ("gradient_opacity", "order"):
            if getattr(lut, name) is not UNSET:
                raise _error(
                    f"{key}.{name}",
                    "set it in [transfer] (it applies to the combined output)",
                    source,
                )
        if field != VALUE_FIELD and lut.points is UNSET and lut.table_range is UNSET:
            raise _error(
                f"{key}.points",
                f"a LUT on field {field!r} needs its function in field integers",
                source,
                "points, or table with table_range",
            )
        tf = transfer_spec(lut, source, f"classification.{key}")
        entries = {} if lut.entries is UNSET else {"entries": lut.entries}
        luts.append(LutSpec(field=field, transfer=tf, **entries))
    big = [i // 2 for i, lut in enumerate(luts) if lut.entries == 4096]
    if len(set(big)) > 1:
        raise _error(
            "luts",
            "4096-entry LUTs feed both leaf ALUs",
            source,
            "4096 entries on lut0/lut1 or on lut2/lut3 only, 256 on the other leaf",
        )
    return tuple(luts)


def parse_classification(
    m: ClassificationModel, source: str, transfer_spec: Callable[..., TransferSpec]
) -> ClassificationSpec:
    """A :class:`ClassificationSpec` from a validated ``[classification]`` table
    (``transfer_spec``: the scene's ``[transfer]`` builder, reused for each LUT's
    function)."""
    fields = _fields(m, source)
    names = [VALUE_FIELD] + [f.name for f in fields]
    if m.value_field is not UNSET and m.value_field not in names[1:]:
        raise _error(
            "value_field",
            f"unknown value {m.value_field!r}",
            source,
            ", ".join(names[1:]) or "none",
        )
    luts = _luts(m, names, source, transfer_spec)
    n = len(luts)
    needed = {"leaf0": n >= 2, "leaf1": n >= 4, "final": n >= 3}
    alus = {}
    for name, must in needed.items():
        op = getattr(m.combine, name)
        if op is UNSET and must:
            raise _error(
                f"combine.{name}", f"is required with {n} LUTs", source, ", ".join(OPCODES)
            )
        if op is not UNSET:
            alus[name] = AluSpec(rgb=op, alpha=op) if isinstance(op, str) else AluSpec(**given(op))
    return ClassificationSpec(
        fields=fields,
        value_field=None if m.value_field is UNSET else m.value_field,
        luts=luts,
        **alus,
    )


def parse_geometry(m: GeometryModel, source: str) -> GeometrySpec:
    """A :class:`GeometrySpec` from a validated ``[geometry]`` table."""

    def error(key: str, message: str, allowed: str | None = None) -> InputError:
        return InputError(message, source=source, key=f"geometry.{key}", allowed=allowed)

    for i, b in enumerate(m.boxes):
        for k in range(3):
            if not b.hi[k] > b.lo[k]:
                raise error(
                    f"boxes[{i}].hi[{k}]",
                    f"{b.hi[k]:g} must exceed lo[{k}] = {b.lo[k]:g}",
                    f"> {b.lo[k]:g}",
                )
    spec = GeometrySpec(
        **given(m)
        | {
            "spheres": tuple(Sphere(**given(s)) for s in m.spheres),
            "boxes": tuple(Box(**given(b)) for b in m.boxes),
        }
    )
    if (spec.color is None) != (spec.depth is None):
        missing = "depth" if spec.depth is None else "color"
        raise error(missing, "give both geometry.color and geometry.depth", "two .npy files")
    if spec.color is not None and (spec.spheres or spec.boxes):
        raise error("color", "give primitives or a color/depth pair, not both")
    if spec.color is None and not (spec.spheres or spec.boxes):
        raise error(
            "spheres", "no geometry", "[[geometry.spheres]], [[geometry.boxes]] or color/depth"
        )
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
