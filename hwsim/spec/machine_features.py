"""What a machine had, and what a scene asks of it: one check for every rung.

# Ref: shared/docs/reference/architectures.md sections 1-5 (each machine's published
#      features); docs/architectures.md ("Declared features", the table by machine).

An architecture file declares its machine's features in ``[features]`` (compositing
modes, classification orders, interpolation, gradient sources, crop, cut planes, early
ray termination, projections, supersampling, classification LUTs, embedded geometry) and
cites each in ``[features.sources]``.  :func:`scene_extensions` lists what a scene asks
outside that set.  :func:`require_machine` refuses the first of them, naming the feature
and the machine, unless the user opted in (``--extend``, or ``[features] extend = true``
in an arch file): the render then runs as a *what-if* and ``stats.json`` lists the
extensions.  Some features cannot be what-ifs because no rung models them (perspective
on a parallel-only order, supersampling outside a machine's range, an interpolation
filter its units lack, more classification LUTs or embedded geometry): those are refused
always.

The same check runs before every rung (golden at a machine's positions included), so a
scene outside the machine is refused, or marked, at all of them alike.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from hwsim.core.errors import InputError
from hwsim.spec.arch import ArchConfig
from hwsim.spec.scene import Scene
from hwsim.spec.scene_features import check_machine

__all__ = [
    "Algorithms",
    "Extension",
    "IDEAL",
    "feature_rows",
    "features_markdown",
    "require_machine",
    "scene_extensions",
]


@dataclass(frozen=True)
class Extension:
    """One thing a scene asks that its machine did not have."""

    feature: str  # the [features] key: "modes"
    key: str  # the scene key asking: "render.mode"
    asked: str  # what the scene asks: "xray"
    machine: str  # what the machine has: "composite, mip"
    source: str  # the declaration's source, tagged

    def describe(self) -> dict[str, Any]:
        """Plain data for stats.json."""
        return asdict(self)


def _listed(arch: ArchConfig, feature: str, key: str, asked: str) -> Extension | None:
    have = getattr(arch, feature)
    if asked in have:
        return None
    return Extension(feature, key, asked, ", ".join(have), _source(arch, feature))


def _source(arch: ArchConfig, feature: str) -> str:
    return arch.feature_sources.get(feature, "[?] not declared in the arch file")


@dataclass(frozen=True)
class Algorithms:
    """The algorithm choices of a machine's datapath (its ``[formats]``): where gradients
    are estimated (``gradient.source``), how samples are shaded (``shade.method``) and the
    reflectance maps' cells per cube-map face edge (``shade.map_size``)."""

    gradient: str
    shading: str
    map_size: int

    def describe_shading(self) -> str:
        """The shading method as stats.json names it."""
        if self.shading == "reflectance-map":
            return f"reflectance-map ({self.map_size}x{self.map_size} cells per cube face)"
        return self.shading


#: The ideal golden renderer's choices: voxel gradients, per-sample Phong.
IDEAL = Algorithms("voxel", "phong", 0)


def scene_extensions(scene: Scene, arch: ArchConfig, algorithms: Algorithms) -> list[Extension]:
    """What ``scene`` asks of ``arch`` outside its declared features (empty: inside).

    ``algorithms`` are the datapath's choices; the gradient source counts where the scene
    needs gradients, the shading method where it is lit.
    """
    gradient_source = algorithms.gradient
    render = scene.render
    found = [_listed(arch, "modes", "render.mode", render.mode)]
    if render.mode == "composite":
        found.append(_listed(arch, "classification", "transfer.order", scene.transfer.order))
        found.append(_listed(arch, "blend_orders", "render.blend_order", render.blend_order))
    if scene.lit or scene.transfer.gradient_opacity is not None:
        found.append(_listed(arch, "gradients", "formats.gradient.source", gradient_source))
    if scene.lit:
        found.append(_listed(arch, "shading", "formats.shade.method", algorithms.shading))
    modulated = scene.transfer.gradient_illumination is not None
    if render.mode == "composite" and scene.lit and modulated and not arch.gradient_illumination:
        source = _source(arch, "gradient_illumination")
        asked = "gradient-magnitude illumination modulation"
        found.append(
            Extension(
                "gradient_illumination", "transfer.gradient_illumination", asked, "none", source
            )
        )
    if scene.cursor is not None and not arch.cursor:
        found.append(Extension("cursor", "cursor", "3-D cursor", "none", _source(arch, "cursor")))
    if scene.crop is not None and not arch.crop:
        found.append(Extension("crop", "crop", "crop box", "none", _source(arch, "crop")))
    if len(scene.cut_planes) > arch.cut_planes:
        asked = f"{len(scene.cut_planes)} cut plane(s)"
        has = f"{arch.cut_planes} at most"
        found.append(Extension("cut_planes", "cut_planes", asked, has, _source(arch, "cut_planes")))
    if render.mode == "composite" and render.early_termination < 1.0 and not arch.early_termination:
        source = _source(arch, "early_termination")
        asked = f"threshold {render.early_termination:g}"
        found.append(
            Extension("early_termination", "render.early_termination", asked, "none", source)
        )
    return [e for e in found if e is not None]


def require_machine(scene: Scene, arch: ArchConfig, algorithms: Algorithms, *, extend: bool):
    """Refuse ``scene`` where ``arch`` cannot render it; return its what-if extensions.

    Raises
    ------
    InputError
        Perspective, supersampling, classification LUTs or embedded geometry beyond the
        machine (never a what-if: no rung models them there), or the first extension
        when neither ``extend`` nor ``arch.extend`` opts in.
    """
    check_machine(scene, arch)  # classification LUTs, embedded geometry
    if scene.view.projection == "perspective" and not arch.perspective:
        raise InputError(
            f"{arch.name} renders parallel projection only",
            source=arch.source,
            key="view.projection",
            allowed="parallel",
        )
    lo, hi = arch.supersampling
    if not lo <= scene.render.supersampling <= hi:
        raise InputError(
            f"{arch.name} supersamples by {lo:g} .. {hi:g} only",
            source=arch.source,
            key="render.supersampling",
            allowed=f"{lo:g} .. {hi:g}",
        )
    if scene.render.interpolation not in arch.interpolation:  # the units interpolate so
        raise InputError(
            f"{arch.name} interpolates {', '.join(arch.interpolation)} only "
            f"({_source(arch, 'interpolation')})",
            source=arch.source,
            key="render.interpolation",
            allowed=", ".join(arch.interpolation),
        )
    if scene.cursor is not None and arch.space_leaping:
        raise InputError(
            f"{arch.name} leaps empty space: its leaps would skip the cursor's samples",
            source=arch.source,
            key="cursor",
            allowed="no [cursor] on a machine with space_leaping",
        )
    gradient_source = algorithms.gradient
    if scene.render.gradient not in (None, gradient_source):
        raise InputError(
            f"{arch.name} estimates gradients at the {gradient_source} positions",
            source=arch.source,
            key="render.gradient",
            allowed=f"{gradient_source} (or omit it; [formats] gradient.source in an arch "
            "file models another machine)",
        )
    extensions = scene_extensions(scene, arch, algorithms)
    if extensions and not (extend or arch.extend):
        e = extensions[0]
        raise InputError(
            f"{arch.name} has no {e.asked} ({e.feature}: {e.machine}; {e.source}); "
            "--extend renders it as a what-if",
            source=arch.source,
            key=e.key,
            allowed=e.machine,
        )
    return extensions


def feature_rows(arch: ArchConfig) -> list[tuple[str, str, str]]:
    """``(feature, what the machine has, source)`` of every declared feature, for
    ``hwsim archs --features`` and the table in docs/architectures.md."""

    def span(lo: float, hi: float) -> str:
        return f"{lo:g}" if lo == hi else f"{lo:g} .. {hi:g}"

    values = {
        "modes": ", ".join(arch.modes),
        "classification": ", ".join(arch.classification),
        "interpolation": ", ".join(arch.interpolation),
        "gradients": ", ".join(arch.gradients),
        "shading": ", ".join(arch.shading),
        "blend_orders": ", ".join(arch.blend_orders),
        "perspective": "parallel, perspective" if arch.perspective else "parallel",
        "supersampling": span(*arch.supersampling),
        "crop": "yes" if arch.crop else "no",
        "gradient_illumination": "yes" if arch.gradient_illumination else "no",
        "cursor": "yes" if arch.cursor else "no",
        "supervolumes": "yes" if arch.supervolumes else "no",
        "cut_planes": str(arch.cut_planes),
        "early_termination": "yes" if arch.early_termination else "no",
        "space_leaping": "yes" if arch.space_leaping else "no",
        "classification_luts": str(arch.classification_luts),
        "embedded_geometry": "yes" if arch.embedded_geometry else "no",
        "sections": f"{arch.section_width} pixels" if arch.section_width else "no",
        "voxel_bits": ", ".join(map(str, arch.voxel_bits)),
        "max_volume": " x ".join(map(str, arch.max_volume)),
    }
    return [(key, value, _source(arch, key)) for key, value in values.items()]


def features_markdown(archs: dict[str, ArchConfig]) -> str:
    """The declared features of ``archs`` as one Markdown table per machine."""
    out = []
    for name, arch in archs.items():
        out += [f"**{name}**", "", "| feature | has | source |", "|---|---|---|"]
        out += [f"| {f} | {v} | {s} |" for f, v, s in feature_rows(arch)]
        out.append("")
    return "\n".join(out)
