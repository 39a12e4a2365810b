"""Architecture configs: one versioned TOML file per machine, kept apart from scenes.

# Ref: shared/docs/reference/architectures.md (published figures, each tagged
#      verified / recalled / inferred; the built-in files cite the tag per value).

The core only validates the generic shape of a machine (pipelines, clock, processing
order, limits, features).  The ``[formats]`` and ``[memory]`` tables are handed to the
models layer, which owns their meaning; the application layer (``hwsim.run.fidelity``)
looks built-in names up in ``models/machines/<family>/*.toml``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hwsim.core.config import Table, read_toml

__all__ = ["ArchConfig", "FEATURE_CHOICES", "parse_arch", "load_arch_file", "ORDERS", "SCHEMA"]

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


@dataclass(frozen=True, kw_only=True)
class ArchConfig:
    """One machine.

    Parameters
    ----------
    name, description : str
        Identity and a one-line summary.
    order : str
        Processing order, one of :data:`ORDERS` (selects the sample positions).
    family : str
        The machine family that models it (``models/machines/<family>``); empty: the
        family registered first for ``order``.
    pipelines : int
        Parallel rendering pipelines, each one sample per clock at best.
    clock_hz : float
        Pipeline clock.
    voxel_bits : tuple of int
        Voxel widths the machine accepts (e.g. ``(8, 12)`` for VolumePro 500); 32: voxels
        that are containers of up to four fields of 4..16 bits (VolumePro 1000), read by
        the value path through one field (``[classification] value_field``).
    max_volume : tuple of int
        Largest volume ``(z, y, x)`` rendered in one pass.
    perspective : bool
        Whether the hardware renders perspective views.
    early_termination, space_leaping : bool
        Acceleration features the machine has.
    supersampling : tuple of float
        Allowed z-supersampling range ``(lo, hi)``.
    cut_planes : int
        Most thick cut planes the machine applies at once.
    classification_luts : int
        Classification LUTs merged by combiners (1: a single LUT; VolumePro 1000: 4).
    embedded_geometry : bool
        Whether opaque geometry can be embedded through image + depth buffers.
    modes, classification, interpolation, gradients, shading, blend_orders : tuple of str
        The declared feature lists (:data:`FEATURE_CHOICES`): compositing modes,
        classification orders, interpolation filters, gradient sources, shading
        methods (per-sample Phong, reflectance maps) and compositing orders (front to
        back, back to front) the machine had.
    crop : bool
        Whether the machine crops to axis slabs (VolumePro's box cropping).
    gradient_illumination : bool
        Whether gradient magnitude can scale diffuse and specular light (VolumePro 500).
    cursor : bool
        Whether the hardware draws a 3-D cursor into the samples (VolumePro 500).
    supervolumes : bool
        Whether the machine's software renders volumes over ``max_volume`` in bricks and
        blends them on the host (VolumePro 500's "supervolumes").
    feature_sources : dict
        ``[features.sources]``: where each declared feature comes from, tagged ``[V]``,
        ``[R]``, ``[I]`` or ``[?]`` as the published figures are.
    extend : bool
        ``[features] extend = true``: render scenes outside the declared set as what-ifs
        (``stats.json`` lists them in ``extensions``) instead of refusing them.
    formats, memory, buffers : dict
        Raw tables for the unit formats, the memory system and on-chip buffer capacities
        (the models layer owns their meaning and validates them).
    slice_overhead_cycles, section_width, section_overhead_cycles : int
        Closed-form timing overheads: cycles lost per slice, the width of a section in
        base-plane pixels (0: no sectioning) and cycles lost per section.
    host_bus_bytes_per_second : float
        The board's bus to the host (0: not modelled): a supervolume's brick images
        travel over it to be blended.
    technology : str
        ``[silicon] technology``: the process node of the machine's era, the energy and
        area model's default (a built-in name of ``hwsim/energy/technologies`` or a file).
    published : dict
        Headline figures to compare against (samples/s, fps at a size), with sources.
    """

    name: str
    description: str = ""
    source: str = "<built-in>"
    order: str = "slice-parallel"
    family: str = ""
    pipelines: int = 4
    clock_hz: float = 125e6
    voxel_bits: tuple[int, ...] = (8, 12, 16)
    max_volume: tuple[int, int, int] = (256, 256, 256)
    perspective: bool = False
    early_termination: bool = False
    space_leaping: bool = False
    supersampling: tuple[float, float] = (1.0, 1.0)
    cut_planes: int = 0
    classification_luts: int = 1
    embedded_geometry: bool = False
    modes: tuple[str, ...] = ("composite",)
    classification: tuple[str, ...] = ("post",)
    interpolation: tuple[str, ...] = ("trilinear",)
    gradients: tuple[str, ...] = ("sample", "voxel")
    shading: tuple[str, ...] = ("phong",)
    blend_orders: tuple[str, ...] = ("front-to-back",)
    crop: bool = False
    gradient_illumination: bool = False
    cursor: bool = False
    supervolumes: bool = False
    feature_sources: dict[str, str] = field(default_factory=dict)
    extend: bool = False
    formats: dict[str, Any] = field(default_factory=dict)
    memory: dict[str, Any] = field(default_factory=dict)
    buffers: dict[str, Any] = field(default_factory=dict)
    published: dict[str, Any] = field(default_factory=dict)
    slice_overhead_cycles: int = 0
    section_width: int = 0
    section_overhead_cycles: int = 0
    host_bus_bytes_per_second: float = 0.0
    technology: str = "cmos45"

    @property
    def value_bits(self) -> tuple[int, ...]:
        """The value path's voxel widths: ``voxel_bits`` without 32 (a 32-bit voxel is a
        container of fields, its value path one field of at most 16 bits)."""
        return tuple(b for b in self.voxel_bits if b <= 16) or (16,)

    @property
    def peak_samples_per_second(self) -> float:
        """Pipelines x clock: one sample per pipeline per clock."""
        return self.pipelines * self.clock_hz

    def to_dict(self) -> dict[str, Any]:
        import dataclasses

        return dataclasses.asdict(self)


def load_arch_file(path: str | Path, name: str | None = None) -> ArchConfig:
    """Read and validate an architecture TOML file."""
    path = Path(path)
    return parse_arch(read_toml(path), source=str(path), name=name or path.stem)


def _family(pipeline: Table) -> str:
    family = pipeline.string("family", "")
    if family and not re.fullmatch(r"[a-z][a-z0-9_]*", family):
        raise pipeline.error("family", f"invalid name {family!r}", "a Python package name")
    return family


#: Every key of ``[features]`` that declares something the machine had (``sources`` may
#: cite each; ``extend`` is the user's opt-in, not a feature).
_FEATURE_KEYS = (
    "perspective",
    "early_termination",
    "space_leaping",
    "supersampling",
    "cut_planes",
    "classification_luts",
    "embedded_geometry",
    *FEATURE_CHOICES,
    "crop",
    "gradient_illumination",
    "cursor",
    "supervolumes",
    "sections",
    "voxel_bits",
    "max_volume",
)


def _declared(features: Table, name: str, default: tuple[str, ...]) -> tuple[str, ...]:
    """A declared feature list: a non-empty list of :data:`FEATURE_CHOICES` values."""
    return features.choices(name, FEATURE_CHOICES[name], list(default))


def _sources(features: Table) -> dict[str, str]:
    """``[features.sources]``: one tagged string per declared feature."""
    table = features.table("sources")
    out = {}
    for key in list(table.data):
        if key not in _FEATURE_KEYS:
            raise table.error(key, "unknown feature", ", ".join(_FEATURE_KEYS))
        out[key] = table.string(key)
    table.finish()
    return out


def parse_arch(data: dict[str, Any], *, source: str, name: str) -> ArchConfig:
    """Validate parsed TOML into an :class:`ArchConfig`."""
    top = Table(data, source)
    top.schema(SCHEMA)
    p = top.table("pipeline", required=True)
    limits = top.table("limits")
    features = top.table("features")
    overheads = top.table("overheads")
    silicon = top.table("silicon")
    bits = limits.choices("voxel_bits", (8, 12, 16, 32), [8, 12, 16])
    max_volume = tuple(int(v) for v in limits.vector("max_volume", 3, [256] * 3, 1, 1 << 16))
    ss = features.vector("supersampling", 2, [1.0, 1.0], 0.125, 16)
    if ss[1] < ss[0]:
        raise features.error("supersampling", "empty range", "[lo, hi] with lo <= hi")
    cfg = ArchConfig(
        name=top.string("name", name),
        description=top.string("description", ""),
        source=source,
        order=p.choice("order", ORDERS),
        family=_family(p),
        pipelines=p.integer("count", lo=1, hi=4096),
        clock_hz=p.number("clock_hz", lo=1.0, hi=10e9),
        voxel_bits=bits,
        max_volume=max_volume,  # type: ignore[arg-type]
        perspective=features.boolean("perspective", False),
        early_termination=features.boolean("early_termination", False),
        space_leaping=features.boolean("space_leaping", False),
        supersampling=ss,  # type: ignore[arg-type]
        cut_planes=features.integer("cut_planes", 0, 0, 64),
        classification_luts=features.integer("classification_luts", 1, 1, 4),
        embedded_geometry=features.boolean("embedded_geometry", False),
        modes=_declared(features, "modes", ("composite",)),
        classification=_declared(features, "classification", ("post",)),
        interpolation=_declared(features, "interpolation", ("trilinear",)),
        gradients=_declared(features, "gradients", ("sample", "voxel")),
        shading=_declared(features, "shading", ("phong",)),
        blend_orders=_declared(features, "blend_orders", ("front-to-back",)),
        crop=features.boolean("crop", False),
        gradient_illumination=features.boolean("gradient_illumination", False),
        cursor=features.boolean("cursor", False),
        supervolumes=features.boolean("supervolumes", False),
        feature_sources=_sources(features),
        extend=features.boolean("extend", False),
        formats=dict(top.table("formats").data),
        memory=dict(top.table("memory").data),
        buffers=dict(top.table("buffers").data),
        published=dict(top.table("published").data),
        slice_overhead_cycles=overheads.integer("slice_cycles", 0, 0, 1 << 20),
        section_width=overheads.integer("section_width", 0, 0, 1 << 16),
        section_overhead_cycles=overheads.integer("section_cycles", 0, 0, 1 << 24),
        host_bus_bytes_per_second=overheads.number("host_bus_bytes_per_second", 0.0, 0, 1e12),
        technology=silicon.string("technology", "cmos45"),
    )
    for t in (p, limits, features, overheads, silicon):
        t.finish()
    top.finish()
    from hwsim.spec.published import parse_published

    # Every figure labelled (fitted, peak or prediction) and checked against the file.
    parse_published(
        cfg.published,
        source=source,
        peak_samples_per_second=cfg.peak_samples_per_second,
        arch_data=data,
    )
    if cfg.memory:
        from hwsim.memory.sdram import parse_memory

        parse_memory(cfg.memory, source=source)  # a bad [memory] table fails at load
    return cfg
