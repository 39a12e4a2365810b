"""A machine's ``[published]`` table: its figures, each labelled with the kind of evidence
it is, read and checked once when the architecture file is loaded.

# Ref: shared/docs/reference/architectures.md (every figure tagged [V]/[R]/[I]);
#      docs/figures.md ("What kind of evidence each row is").

A figure is worth only what its derivation leaves independent.  Every figure says which
of three kinds it is:

``fitted``
    a machine parameter was set from this figure (or from a product it restates): the
    comparison can only show the modelled overheads on top of the fit;
``peak``
    the figure is pipelines x clock restated (``P f``, ``N^3 / (P f)``): simulated over
    published measures only what the model loses below one sample per pipeline per clock;
``prediction``
    no parameter of the machine came from it: the row is an error, whatever it is.

``fitted_from`` lists the architecture keys set from the figure (dotted, as in the file:
``pipeline.clock_hz``): required for ``fitted``, empty for ``prediction``.  A figure that
is the file's own ``P x f`` restated (within 1 %) cannot be labelled a prediction: the
check is arithmetic, so a mislabelled row is refused when the file is read, whichever
figure it is.

Headline figures are keys ``fps_N``, ``seconds_N`` and ``samples_per_second`` on the dense
scenario (``N^3`` head phantom, one sample per voxel).  Figures measured on other
scenarios (a named data set's size, supersampling, early termination) are entries of
``[[published.measured]]``; see :class:`Scenario`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from msgspec import Meta

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, between, finite_at_least, integer, validate

__all__ = [
    "EVIDENCE",
    "METRICS",
    "PublishedFigure",
    "Scenario",
    "TIME_METRICS",
    "parse_published",
    "restates_peak",
]

#: The kinds of evidence a figure can be (docs/figures.md).
EVIDENCE = ("fitted", "peak", "prediction")
#: What a figure measures: a frame's time, or the fraction of block-cache lookups that hit
#: (a measured memory figure, from the rung's ``cache.hits`` / ``cache.lookups``).
METRICS = ("fps", "seconds", "samples_per_second", "cache_hit_rate")
#: The metrics that are a frame's time (what pipelines x clock can restate).
TIME_METRICS = METRICS[:3]
#: Scenario side used for ``samples_per_second`` when the file names no size.
DEFAULT_SIZE = 256
#: Relative closeness at which a figure counts as ``P x f`` restated.
PEAK_CLOSENESS = 0.01
_NAME = re.compile(r"^[a-z0-9][a-z0-9_.-]{0,63}$")
_HEADLINE = re.compile(r"^(fps|seconds)_(\d+)$")


@dataclass(frozen=True)
class Scenario:
    """What a figure is measured on.

    ``volume`` is the data set's ``(x, y, z)`` voxels, rendered as the CT-like head
    phantom at that size (cubic volumes only, for now): a named data set's content is not
    available, so a machine that visits every sample is timed as on
    the data, and one that terminates rays early is timed on the phantom's opacity, which
    a row's note must say.  ``image`` is ``(width, height)`` (None: one pixel per voxel
    across the volume, as the dense scenario).  ``early_termination`` is the opacity
    threshold (1.0: off).  The rest are the render settings the source states.
    """

    volume: tuple[int, int, int]
    image: tuple[int, int] | None = None
    supersampling: float = 1.0
    early_termination: float = 1.0
    mode: str = "composite"
    view: tuple[float, float] = (0.0, 0.0)
    projection: str = "parallel"
    description: str = ""

    @property
    def voxels(self) -> int:
        x, y, z = self.volume
        return x * y * z

    @property
    def dense(self) -> bool:
        """The headline dense scenario: an ``N^3`` head, one sample per voxel."""
        x, y, z = self.volume
        return (
            x == y == z
            and self.image is None
            and self.supersampling == 1.0
            and self.early_termination >= 1.0
            and self.mode == "composite"
            and self.view == (0.0, 0.0)
            and self.projection == "parallel"
        )

    def text(self) -> str:
        if self.description:
            return self.description
        x, y, z = self.volume
        if self.dense:
            return f"dense head {x}^3"
        parts = [f"head {x}x{y}x{z}", self.projection]
        if self.image is not None:
            parts.append(f"image {self.image[0]}x{self.image[1]}")
        if self.supersampling != 1.0:
            parts.append(f"supersampling {self.supersampling:g}")
        if self.early_termination < 1.0:
            parts.append(f"early termination at {self.early_termination:g}")
        if self.mode != "composite":
            parts.append(self.mode)
        return ", ".join(parts)


@dataclass(frozen=True)
class PublishedFigure:
    """One published figure: the only place a figure is written."""

    key: str
    value: float
    metric: str  # one of METRICS
    scenario: Scenario
    evidence: str  # one of EVIDENCE
    fitted_from: tuple[str, ...] = ()
    tolerance: float | None = None  # the acceptance band, where the file sets one
    note: str = ""
    source: str = ""  # tagged [V]/[R]/[I] citation (measured figures)
    kind: str = "stated"  # "measured" (on hardware), "simulated" (by its authors), "stated"

    @property
    def size(self) -> int:
        """The scenario's largest side (what ``--max-size`` compares)."""
        return max(self.scenario.volume)


def restates_peak(metric: str, value: float, scenario: Scenario, peak: float) -> bool:
    """Whether ``value`` is ``peak`` samples/s restated on ``scenario`` (within 1 %): one
    sample per voxel at ``P x f``, or the rate itself."""
    if metric not in TIME_METRICS:
        return False
    if scenario.supersampling != 1.0 or scenario.early_termination < 1.0:
        return False
    n = scenario.voxels
    implied = {
        "samples_per_second": value,
        "fps": value * n,
        "seconds": n / value if value > 0 else float("inf"),
    }[metric]
    return abs(implied / peak - 1.0) <= PEAK_CLOSENESS


def _headline_scenario(key: str, sizes: list[int]) -> tuple[str, Scenario] | None:
    m = _HEADLINE.match(key)
    if m:
        n = int(m.group(2))
        return m.group(1), Scenario((n, n, n))
    if key == "samples_per_second":
        n = min(sizes) if sizes else DEFAULT_SIZE
        return "samples_per_second", Scenario((n, n, n))
    return None


def _keys_in(data: dict[str, Any]) -> set[str]:
    """Every dotted key of a parsed TOML file (tables' own names included)."""
    out: set[str] = set()
    stack: list[tuple[str, Any]] = [("", data)]
    while stack:
        prefix, table = stack.pop()
        for k, v in table.items():
            dotted = f"{prefix}{k}"
            out.add(dotted)
            if isinstance(v, dict):
                stack.append((dotted + ".", v))
    return out


Positive = finite_at_least(0.0, open_lo=True)
Evidence = Literal[EVIDENCE]  # type: ignore[valid-type]
Tolerance = between(0.0, 10.0)
Side = integer(2, 1 << 12)
Pixels = integer(1, 1 << 13)
Angle = between(-360.0, 360.0)
#: The tables of ``[published]`` that are not headline figures.
_TABLES = ("tolerance", "notes", "evidence", "fitted_from", "measured")


class Measured(Schema):
    """One ``[[published.measured]]`` figure: give exactly one of :data:`METRICS`."""

    name: Annotated[str, Meta(pattern=_NAME.pattern)]
    volume: tuple[Side, Side, Side]
    source: str
    kind: Literal["measured", "simulated", "stated"]
    fps: Positive | None = None
    seconds: Positive | None = None
    samples_per_second: Positive | None = None
    cache_hit_rate: between(0.0, 1.0, open_lo=True) | None = None
    image: tuple[Pixels, Pixels] | None = None
    supersampling: between(0.125, 16.0) = 1.0
    early_termination: between(0.0, 1.0, open_lo=True) = 1.0
    mode: Literal["composite", "mip"] = "composite"
    view: tuple[Angle, Angle] = (0.0, 0.0)
    projection: Literal["parallel", "perspective"] = "parallel"
    scenario: str = ""
    evidence: Evidence = "prediction"
    fitted_from: tuple[str, ...] = ()
    tolerance: Tolerance | None = None
    note: str = ""


class Labels(Schema):
    """The label tables of ``[published]``, each keyed by headline figure, and the
    measured figures."""

    tolerance: dict[str, Tolerance] = {}
    notes: dict[str, str] = {}
    evidence: dict[str, Evidence] = {}
    fitted_from: dict[str, tuple[str, ...]] = {}
    measured: tuple[Measured, ...] = ()
    voxels_per_axis: integer(1, 1 << 16) | None = None  # a fact beside the figures


def _check_fitted(
    fitted: tuple[str, ...], evidence: str, arch_keys: set[str] | None, source: str, key: str
) -> tuple[str, ...]:
    """``fitted_from`` against the figure's evidence and the file's keys."""
    allowed = 'a list of the file\'s dotted keys, e.g. ["pipeline.clock_hz"]'
    for v in fitted:
        if arch_keys is not None and v not in arch_keys:
            raise InputError(
                f"{v!r} is not a key of this file", source=source, key=key, allowed=allowed
            )
    if evidence == "fitted" and not fitted:
        raise InputError(
            "a fitted figure must name the keys set from it",
            source=source,
            key=key,
            allowed=allowed,
        )
    if evidence == "prediction" and fitted:
        raise InputError(
            "a prediction has no fitted keys",
            source=source,
            key=key,
            allowed="[] (or label it fitted)",
        )
    return fitted


def _check_label(
    fig: PublishedFigure, peak: float | None, source: str, key: str
) -> PublishedFigure:
    if (
        peak
        and fig.evidence == "prediction"
        and restates_peak(fig.metric, fig.value, fig.scenario, peak)
    ):
        raise InputError(
            f"{fig.value:g} is the file's pipelines x clock ({peak:g} samples/s) restated, "
            "not a prediction",
            source=source,
            key=key,
            allowed="peak or fitted",
        )
    return fig


def _measured(
    m: Measured, i: int, keys: set[str], arch_keys: set[str] | None, peak: float | None, source: str
) -> PublishedFigure:
    at = f"published.measured[{i}]"
    if m.name in keys:
        raise InputError(
            f"{m.name!r} is already a figure of this file",
            source=source,
            key=f"{at}.name",
            allowed="a new name",
        )
    given = [metric for metric in METRICS if getattr(m, metric) is not None]
    if len(given) != 1:
        raise InputError(
            f"give exactly one of {', '.join(METRICS)}",
            source=source,
            key=f"{at}.fps",
            allowed="one",
        )
    if len(set(m.volume)) != 1:
        raise InputError(
            f"invalid {list(m.volume)!r}",
            source=source,
            key=f"{at}.volume",
            allowed="[n, n, n] whole voxels",
        )
    scenario = Scenario(
        volume=m.volume,
        image=m.image,
        supersampling=m.supersampling,
        early_termination=m.early_termination,
        mode=m.mode,
        view=m.view,
        projection=m.projection,
        description=m.scenario,
    )
    fig = PublishedFigure(
        key=m.name,
        value=getattr(m, given[0]),
        metric=given[0],
        scenario=scenario,
        evidence=m.evidence,
        fitted_from=_check_fitted(
            m.fitted_from, m.evidence, arch_keys, source, f"{at}.fitted_from"
        ),
        tolerance=m.tolerance,
        note=m.note,
        source=m.source,
        kind=m.kind,
    )
    return _check_label(fig, peak, source, f"{at}.evidence")


def _headline(
    data: dict[str, Any],
    labels: Labels,
    arch_keys: set[str] | None,
    peak: float | None,
    source: str,
) -> list[PublishedFigure]:
    """The headline figures (``fps_N``, ``seconds_N``, ``samples_per_second``) with the
    labels the label tables give them; a label for a figure the file lacks is a typo."""
    values = {k: v for k, v in data.items() if k not in _TABLES and k != "voxels_per_axis"}
    sizes = [int(m.group(2)) for k in values if (m := _HEADLINE.match(k))]
    parsed = {key: _headline_scenario(key, sizes) for key in values}
    for key, found in parsed.items():
        if found is None:
            raise InputError(
                "unknown figure",
                source=source,
                key=f"published.{key}",
                allowed="fps_N, seconds_N, samples_per_second",
            )
    values = validate(values, dict[str, Positive], source, prefix="published")
    for table in ("tolerance", "notes", "evidence", "fitted_from"):
        for key in getattr(labels, table):
            if key not in values:
                allowed = ", ".join(values) or "none"
                raise InputError(
                    "unknown key", source=source, key=f"published.{table}.{key}", allowed=allowed
                )
    out = []
    for key, value in values.items():
        if key not in labels.evidence:
            raise InputError(
                "is required",
                source=source,
                key=f"published.evidence.{key}",
                allowed=", ".join(EVIDENCE),
            )
        metric, scenario = parsed[key]  # type: ignore[misc]
        evidence = labels.evidence[key]
        fitted = labels.fitted_from.get(key, ())
        fig = PublishedFigure(
            key=key,
            value=value,
            metric=metric,
            scenario=scenario,
            evidence=evidence,
            fitted_from=_check_fitted(
                fitted, evidence, arch_keys, source, f"published.fitted_from.{key}"
            ),
            tolerance=labels.tolerance.get(key),
            note=labels.notes.get(key, ""),
        )
        out.append(_check_label(fig, peak, source, f"published.evidence.{key}"))
    return out


def parse_published(
    data: Any,
    *,
    source: str,
    peak_samples_per_second: float | None = None,
    arch_data: dict[str, Any] | None = None,
) -> list[PublishedFigure]:
    """The figures of a ``[published]`` table, in file order (headline keys, then the
    ``[[published.measured]]`` entries).

    Types and ranges are :class:`Labels` and :class:`Measured`; then every figure must
    carry ``evidence``; a bad label, an unknown ``fitted_from`` key (checked against
    ``arch_data``, the whole file, when given) or a prediction that restates
    ``peak_samples_per_second`` raises :class:`InputError` naming the key.
    """
    data = validate(data, dict[str, Any], source, prefix="published")
    labels = validate(
        {k: v for k, v in data.items() if k in (*_TABLES, "voxels_per_axis")},
        Labels,
        source,
        prefix="published",
    )
    arch_keys = _keys_in(arch_data) if arch_data is not None else None
    peak = peak_samples_per_second
    out = _headline(data, labels, arch_keys, peak, source)
    keys = {f.key for f in out}
    for i, m in enumerate(labels.measured):
        fig = _measured(m, i, keys, arch_keys, peak, source)
        keys.add(fig.key)
        out.append(fig)
    return out
