"""One architecture's fixed-point datapath: the unit configs its ``[formats]`` table sets.

# Ref: shared/docs/reference/architectures.md section 9.1 (suggested widths);
#      docs/numerics.md (every format, rounding and bound).

``[formats]`` keys are ``<unit>.<field>`` (``interp.weight_bits = 9``); anything absent
takes the unit's default (VolumePro 500 values).  :data:`FormatsTable` is the table's
model (built from the unit configs' fields); an unknown key, a wrong type or a value
outside the unit's range is refused with the file and key named, when the architecture
file is loaded (:func:`models.machines.check_tables`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import msgspec
from msgspec.structs import asdict

from hwsim.core.config import flatten_table
from hwsim.core.errors import InputError
from hwsim.core.models import Finite, Schema, integer, validate
from hwsim.spec.arch import ArchConfig
from models.units.classify import ClassifyConfig
from models.units.composite import CompositeConfig
from models.units.gradient import GradientConfig
from models.units.interp import InterpConfig
from models.units.shade import ShadeConfig

__all__ = [
    "DATAPATH_UNITS",
    "Datapath",
    "FormatsTable",
    "UNIT_CONFIGS",
    "formats_of",
    "units_needed",
]

UNIT_CONFIGS = {
    "interp": InterpConfig,
    "gradient": GradientConfig,
    "classify": ClassifyConfig,
    "shade": ShadeConfig,
    "composite": CompositeConfig,
}


#: The datapath units of every machine, in dataflow order.
DATAPATH_UNITS = ("interp", "gradient", "classify", "shade", "composite", "crop")


def units_needed(scene, modulates: bool) -> dict[str, bool]:
    """Which datapath units ``scene`` uses (design section 3, "model only what a scene
    requires"): the one rule every rung reports and the cycle models elide by.
    ``modulates``: its transfer function scales opacity by gradient magnitude.  Iso
    surfaces use no classification (the hit colour is the scene's ``iso_color``)."""
    composite = scene.render.mode == "composite"
    return {
        "interp": True,
        "gradient": scene.lit or (composite and modulates),
        "classify": composite,
        "shade": scene.lit,
        "composite": True,
        "crop": scene.crop is not None or bool(scene.cut_planes),
    }


@dataclass(frozen=True, kw_only=True)
class Datapath:
    """Voxel width and the config of every unit, as one architecture sets them."""

    voxel_bits: int = 12
    interp: InterpConfig = field(default_factory=InterpConfig)
    gradient: GradientConfig = field(default_factory=GradientConfig)
    classify: ClassifyConfig = field(default_factory=ClassifyConfig)
    shade: ShadeConfig = field(default_factory=ShadeConfig)
    composite: CompositeConfig = field(default_factory=CompositeConfig)

    @classmethod
    def from_arch(
        cls, arch: ArchConfig, data_bits: int, overrides: dict[str, Any] | None = None
    ) -> Datapath:
        """The datapath of ``arch`` for data of ``data_bits`` (0 for float data).

        The voxel width is the narrowest the machine accepts that holds the data, else its
        widest.  ``overrides`` (``{"interp.weight_bits": 6}``) win over the file, for
        bit-width sweeps.  The table is validated against :data:`FormatsTable` (keys and
        types), then by each unit's config (its ranges).
        """
        fitting = [b for b in sorted(arch.value_bits) if data_bits and b >= data_bits]
        doc = formats_of(arch, overrides)
        configs: dict[str, Any] = {}
        for unit, config in UNIT_CONFIGS.items():
            fields = asdict(getattr(doc, unit))
            if unit == "shade":  # one source of truth: the shader reads the gradient's normals
                fields["normal_frac_bits"] = configs["gradient"].normal_frac_bits
            try:
                configs[unit] = config(**fields)  # the unit's own ranges
            except (TypeError, ValueError) as exc:
                raise InputError(
                    f"invalid format: {exc}", source=arch.source, key=f"formats.{unit}"
                ) from None
        voxel_bits = doc.voxel.bits or (fitting[0] if fitting else max(arch.value_bits))
        return cls(voxel_bits=voxel_bits, **configs)

    @classmethod
    def for_volume(cls, arch: ArchConfig, volume) -> Datapath:
        """The datapath of ``arch`` for ``volume``'s data (integer bits; 0 for float data)."""
        bits = volume.bits if volume.data.dtype.kind in "iu" else 0
        return cls.from_arch(arch, bits)

    def describe(self) -> dict[str, Any]:
        """Plain data for stats.json."""
        out: dict[str, Any] = {"voxel_bits": self.voxel_bits}
        for unit in UNIT_CONFIGS:
            out[unit] = dataclasses.asdict(getattr(self, unit))
        return out


#: A unit config field's type in the model, by the type of its default (any other: the
#: config's own checks decide).
_KINDS: dict[type, Any] = {int: int, str: str, bool: bool, float: Finite}


def _unit_table(unit: str, config: type) -> type[Schema]:
    """The ``[formats.<unit>]`` model: the unit config's fields, typed and defaulted as the
    config declares them (its ranges stay the config's own checks).  The shader has no
    ``normal_frac_bits`` of its own: it reads the gradient unit's."""
    fields = [
        (f.name, _KINDS.get(type(f.default), Any), f.default)
        for f in dataclasses.fields(config)
        if (unit, f.name) != ("shade", "normal_frac_bits")
    ]
    return msgspec.defstruct(f"{unit}_formats", fields, bases=(Schema,), module=__name__)


class VoxelFormats(Schema):
    """``[formats.voxel]``: a voxel width that overrides the machine's choice."""

    bits: integer(1, 32) | None = None


#: ``[formats]``: one table per unit of :data:`UNIT_CONFIGS` and ``voxel``.
FormatsTable = msgspec.defstruct(
    "FormatsTable",
    [("voxel", VoxelFormats, msgspec.field(default_factory=VoxelFormats))]
    + [
        (unit, model, msgspec.field(default_factory=model))
        for unit, model in ((u, _unit_table(u, c)) for u, c in UNIT_CONFIGS.items())
    ],
    bases=(Schema,),
    module=__name__,
)


def formats_of(arch: ArchConfig, overrides: dict[str, Any] | None = None) -> Any:
    """``arch.formats`` (nested, as TOML reads ``interp.weight_bits = 9``, or flat, as a
    sweep's overrides name keys) with ``overrides``, validated as :data:`FormatsTable`."""
    nested: dict[str, Any] = {}
    for key, value in {**flatten_table(arch.formats), **(overrides or {})}.items():
        unit, dot, name = key.partition(".")
        if not dot:
            nested[unit] = value  # a unit given a value, not a table: the model says so
        elif isinstance(nested.setdefault(unit, {}), dict):
            nested[unit][name] = value
    if "normal_frac_bits" in (nested.get("shade") or {}):
        raise InputError(
            "the shader reads the gradient unit's normals",
            source=arch.source,
            key="formats.shade.normal_frac_bits",
            allowed="set gradient.normal_frac_bits instead",
        )
    return validate(nested, FormatsTable, arch.source, prefix="formats")
