"""The architecture file's model: every key, its type, range and default, declared once.

# Ref: docs/architectures.md (the keys of an architecture file; this module is their
#      source of truth).

:func:`hwsim.spec.arch.parse_arch` validates a parsed file against :class:`ArchFile`
(:func:`hwsim.core.models.validate`: a wrong type, a missing or unknown key, a value out
of range is one line naming the file and the key path) and builds the
:class:`~hwsim.spec.arch.ArchConfig` from it.  The generic shape lives here; the tables
whose meaning a machine family owns (``[formats]``, ``[memory]``, ``[buffers]``) are
tables here and validated by their owners' models when the file is loaded
(:func:`hwsim.spec.arch.parse_arch` for ``[memory]`` and ``[published]``, the machine
registry for the rest, :func:`models.machines.check_tables`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import msgspec
from msgspec import Meta

from hwsim.core.models import Schema, between, count, integer

__all__ = ["ArchFile", "FEATURE_CHOICES", "FEATURE_KEYS", "ORDERS", "SCHEMA"]

SCHEMA = 1
#: Processing orders, named by the sample positions they produce (hwsim.golden plans).
ORDERS = ("shear-warp", "slice-parallel", "shear-image", "ray")
#: The declared feature lists of ``[features]`` and what each may hold (the scene's
#: ``render.mode``, ``transfer.order``, ``render.interpolation``; gradients estimated at
#: interpolated samples or at voxels and then interpolated).
FEATURE_CHOICES = {
    "modes": ("composite", "mip", "minip", "xray", "iso"),
    "classification": ("post", "pre"),
    "interpolation": ("trilinear", "nearest", "cubic"),
    "gradients": ("sample", "voxel"),
    "shading": ("phong", "reflectance-map"),
    "blend_orders": ("front-to-back", "back-to-front"),
}

Order = Literal[ORDERS]  # type: ignore[valid-type]
VoxelBits = Literal[8, 12, 16, 32]
Side = integer(1, 1 << 16)
Ratio = between(0.125, 16)


def _listed(name: str) -> Any:
    """A declared feature list: a non-empty list of :data:`FEATURE_CHOICES` ``[name]``."""
    return Annotated[tuple[Literal[FEATURE_CHOICES[name]], ...], Meta(min_length=1)]  # type: ignore[valid-type]


Modes = _listed("modes")
Classification = _listed("classification")
Interpolation = _listed("interpolation")
Gradients = _listed("gradients")
Shading = _listed("shading")
BlendOrders = _listed("blend_orders")


class Pipeline(Schema):
    """``[pipeline]``: the processing order, family, pipelines and clock."""

    order: Order
    count: count(4096)
    clock_hz: between(1.0, 10e9)
    family: Annotated[str, Meta(pattern=r"^([a-z][a-z0-9_]*)?$")] = ""


class Limits(Schema):
    """``[limits]``: voxel widths accepted and the largest volume of one pass."""

    voxel_bits: Annotated[tuple[VoxelBits, ...], Meta(min_length=1)] = (8, 12, 16)
    max_volume: tuple[Side, Side, Side] = (256, 256, 256)


class Sources(Schema):
    """``[features.sources]``: a tagged citation per declared feature (every key optional)."""

    perspective: str | None = None
    early_termination: str | None = None
    space_leaping: str | None = None
    supersampling: str | None = None
    cut_planes: str | None = None
    classification_luts: str | None = None
    embedded_geometry: str | None = None
    modes: str | None = None
    classification: str | None = None
    interpolation: str | None = None
    gradients: str | None = None
    shading: str | None = None
    blend_orders: str | None = None
    crop: str | None = None
    gradient_illumination: str | None = None
    cursor: str | None = None
    supervolumes: str | None = None
    sections: str | None = None
    voxel_bits: str | None = None
    max_volume: str | None = None


#: Every key of ``[features]`` that declares something the machine had (``sources`` may
#: cite each; ``extend`` is the user's opt-in, not a feature).
FEATURE_KEYS = tuple(f.encode_name for f in msgspec.structs.fields(Sources))


class Features(Schema):
    """``[features]``: what the machine had (docs/architectures.md, "Declared features")."""

    perspective: bool = False
    early_termination: bool = False
    space_leaping: bool = False
    supersampling: tuple[Ratio, Ratio] = (1.0, 1.0)
    cut_planes: integer(0, 64) = 0
    classification_luts: integer(1, 4) = 1
    embedded_geometry: bool = False
    modes: Modes = ("composite",)
    classification: Classification = ("post",)
    interpolation: Interpolation = ("trilinear",)
    gradients: Gradients = ("sample", "voxel")
    shading: Shading = ("phong",)
    blend_orders: BlendOrders = ("front-to-back",)
    crop: bool = False
    gradient_illumination: bool = False
    cursor: bool = False
    supervolumes: bool = False
    sources: Sources = msgspec.field(default_factory=Sources)
    extend: bool = False


class Overheads(Schema):
    """``[overheads]``: the closed-form timing overheads and the host bus."""

    slice_cycles: integer(0, 1 << 20) = 0
    section_width: integer(0, 1 << 16) = 0
    section_cycles: integer(0, 1 << 24) = 0
    host_bus_bytes_per_second: between(0, 1e12) = 0.0


class Silicon(Schema):
    """``[silicon]``: the technology the energy and area model prices the machine in."""

    technology: str = "cmos45"


class ArchFile(Schema):
    """An architecture file.  ``[formats]``, ``[memory]``, ``[buffers]`` and
    ``[published]`` are tables here; their owners' models check their keys."""

    pipeline: Pipeline
    schema: Literal[1] = SCHEMA
    name: str | None = None
    description: str = ""
    limits: Limits = msgspec.field(default_factory=Limits)
    features: Features = msgspec.field(default_factory=Features)
    overheads: Overheads = msgspec.field(default_factory=Overheads)
    silicon: Silicon = msgspec.field(default_factory=Silicon)
    formats: dict[str, Any] = {}
    memory: dict[str, Any] = {}
    buffers: dict[str, Any] = {}
    published: dict[str, Any] = {}
