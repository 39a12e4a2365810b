"""One architecture's fixed-point datapath: the unit configs its ``[formats]`` table sets.

# Ref: shared/docs/reference/architectures.md section 9.1 (suggested widths);
#      docs/numerics.md (every format, rounding and bound).

``[formats]`` keys are ``<unit>.<field>`` (``interp.weight_bits = 9``); anything absent
takes the unit's default (VolumePro 500 values).  An unknown key or a value outside the
unit's range is refused with the file and key named.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from hwsim.core.config import flatten_table
from hwsim.core.errors import InputError
from hwsim.spec.arch import ArchConfig
from models.units.classify import ClassifyConfig
from models.units.composite import CompositeConfig
from models.units.gradient import GradientConfig
from models.units.interp import InterpConfig
from models.units.shade import ShadeConfig

__all__ = ["DATAPATH_UNITS", "Datapath", "UNIT_CONFIGS", "units_needed"]

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
        bit-width sweeps.
        """
        fitting = [b for b in sorted(arch.value_bits) if data_bits and b >= data_bits]
        voxel_bits = fitting[0] if fitting else max(arch.value_bits)
        table = {**flatten_table(arch.formats), **(overrides or {})}
        units: dict[str, dict[str, Any]] = {name: {} for name in UNIT_CONFIGS}
        for key, value in table.items():
            unit, _, name = key.partition(".")
            if unit == "voxel" and name == "bits":
                voxel_bits = _typed(value, 0, arch.source, "formats.voxel.bits")
                continue
            fields = (
                {f.name for f in dataclasses.fields(UNIT_CONFIGS.get(unit, object))}
                if unit in UNIT_CONFIGS
                else set()
            )
            if name not in fields:
                allowed = ", ".join(
                    f"{u}.{f.name}" for u, c in UNIT_CONFIGS.items() for f in dataclasses.fields(c)
                )
                raise InputError(
                    "unknown format key", source=arch.source, key=f"formats.{key}", allowed=allowed
                )
            default = next(f for f in dataclasses.fields(UNIT_CONFIGS[unit]) if f.name == name)
            units[unit][name] = _typed(value, default.default, arch.source, f"formats.{key}")
        if "normal_frac_bits" in units["shade"]:
            raise InputError(
                "the shader reads the gradient unit's normals",
                source=arch.source,
                key="formats.shade.normal_frac_bits",
                allowed="set gradient.normal_frac_bits instead",
            )
        try:
            configs = {unit: UNIT_CONFIGS[unit](**kw) for unit, kw in units.items()}
            # One source of truth: the shader's input format is the gradient's output.
            configs["shade"] = dataclasses.replace(
                configs["shade"], normal_frac_bits=configs["gradient"].normal_frac_bits
            )
        except (TypeError, ValueError) as exc:
            raise InputError(f"invalid format: {exc}", source=arch.source, key="formats") from None
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


def _typed(value: Any, default: Any, source: str, key: str) -> Any:
    """``value`` if it has the type of the field's ``default`` (an int is a float too).

    A float where a bit width belongs is refused here, naming the key, rather than deep
    inside the compiled kernels.
    """
    kind = type(default)
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        ok = ok and math.isfinite(value)
    else:
        ok = isinstance(value, kind)
    if not ok:
        names = {bool: "true or false", int: "an integer", float: "a finite number"}
        raise InputError(
            f"{value!r} is not {names.get(kind, kind.__name__)}",
            source=source,
            key=key,
            allowed=names.get(kind, kind.__name__),
        )
    return float(value) if kind is float else value
