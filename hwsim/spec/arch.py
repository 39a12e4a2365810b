"""Architecture configs: one versioned TOML file per machine, kept apart from scenes.

# Ref: shared/docs/reference/architectures.md (published figures, each tagged
#      verified / recalled / inferred; the built-in files cite the tag per value).

The file's model is :class:`hwsim.spec.arch_schema.ArchFile` (with ``[published]``'s and
``[memory]``'s, checked here too).  The tables whose meaning the models layer owns
(``[formats]``, a family's ``[buffers]`` and its rules across tables) are checked by the
machine registry right after this load (:func:`models.machines.check_tables`), which the
application layer asks for every file it loads (:func:`hwsim.run.fidelity.load_machine`:
built-in names are looked up in ``models/machines/<family>/*.toml``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hwsim.core.config import read_toml
from hwsim.core.errors import InputError
from hwsim.core.models import validate
from hwsim.spec.arch_schema import FEATURE_CHOICES, ORDERS, SCHEMA, ArchFile

__all__ = ["ArchConfig", "FEATURE_CHOICES", "parse_arch", "load_arch_file", "ORDERS", "SCHEMA"]


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
        The tables of the unit formats, the memory system and on-chip buffer capacities,
        as the file gives them (their models: ``models.datapath.FormatsTable``,
        :data:`hwsim.memory.sdram.MemoryTable`, the family's ``Machine.buffers``; all
        checked when the file is loaded).
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
    """Read and validate an architecture TOML file (its generic shape, ``[published]``
    and ``[memory]``; the machine registry checks the family's own tables)."""
    path = Path(path)
    return parse_arch(read_toml(path), source=str(path), name=name or path.stem)


def parse_arch(data: dict[str, Any], *, source: str, name: str) -> ArchConfig:
    """Validate parsed TOML against :class:`~hwsim.spec.arch_schema.ArchFile` into an
    :class:`ArchConfig`; then the rules across keys: a supersampling range ``lo <= hi``,
    every ``[published]`` figure labelled (fitted, peak or prediction) and checked against
    the file, a consistent ``[memory]`` table."""
    doc = validate(data, ArchFile, source)
    p, limits, features, overheads = doc.pipeline, doc.limits, doc.features, doc.overheads
    lo, hi = features.supersampling
    if hi < lo:
        raise InputError(
            "empty range",
            source=source,
            key="features.supersampling",
            allowed="[lo, hi] with lo <= hi",
        )
    lists = {key: getattr(features, key) for key in FEATURE_CHOICES}
    cited = data.get("features", {}).get("sources", {})  # file order, every value a string
    cfg = ArchConfig(
        name=name if doc.name is None else doc.name,
        description=doc.description,
        source=source,
        order=p.order,
        family=p.family,
        pipelines=p.count,
        clock_hz=p.clock_hz,
        voxel_bits=limits.voxel_bits,
        max_volume=limits.max_volume,
        perspective=features.perspective,
        early_termination=features.early_termination,
        space_leaping=features.space_leaping,
        supersampling=(lo, hi),
        cut_planes=features.cut_planes,
        classification_luts=features.classification_luts,
        embedded_geometry=features.embedded_geometry,
        **lists,
        crop=features.crop,
        gradient_illumination=features.gradient_illumination,
        cursor=features.cursor,
        supervolumes=features.supervolumes,
        feature_sources=dict(cited),
        extend=features.extend,
        formats=dict(doc.formats),
        memory=dict(doc.memory),
        buffers=dict(doc.buffers),
        published=dict(doc.published),
        slice_overhead_cycles=overheads.slice_cycles,
        section_width=overheads.section_width,
        section_overhead_cycles=overheads.section_cycles,
        host_bus_bytes_per_second=overheads.host_bus_bytes_per_second,
        technology=doc.silicon.technology,
    )
    from hwsim.spec.published import parse_published

    parse_published(
        cfg.published,
        source=source,
        peak_samples_per_second=cfg.peak_samples_per_second,
        arch_data=data,
    )
    from hwsim.memory.sdram import parse_memory

    parse_memory(cfg.memory, source=source)  # a bad [memory] table fails at load
    return cfg
