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
from typing import Any

from hwsim.core.config import Table

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


def _fitted_from(
    table: Table, name: str, evidence: str, arch_keys: set[str] | None
) -> tuple[str, ...]:
    value = table.raw(name, [])
    allowed = 'a list of the file\'s dotted keys, e.g. ["pipeline.clock_hz"]'
    if not isinstance(value, list) or any(not isinstance(v, str) for v in value):
        raise table.error(name, f"must be a list of key names, got {value!r}", allowed)
    for v in value:
        if arch_keys is not None and v not in arch_keys:
            raise table.error(name, f"{v!r} is not a key of this file", allowed)
    if evidence == "fitted" and not value:
        raise table.error(name, "a fitted figure must name the keys set from it", allowed)
    if evidence == "prediction" and value:
        raise table.error(name, "a prediction has no fitted keys", "[] (or label it fitted)")
    return tuple(value)


def _labels(
    evidence: str,
    arch_keys: set[str] | None,
    fitted_from: tuple[Table, str],
    tolerance: tuple[Table, str],
    note: tuple[Table, str],
) -> dict[str, Any]:
    """A figure's ``fitted_from``, ``tolerance`` and ``note``, each read from its
    ``(table, key)``: the figure's own table (``[[published.measured]]``) or the file's
    label table keyed by the figure (a headline figure)."""
    (tol_t, tol_key), (note_t, note_key) = tolerance, note
    return {
        "fitted_from": _fitted_from(*fitted_from, evidence, arch_keys),
        "tolerance": tol_t.number(tol_key, None, 0.0, 10.0) if tol_t.has(tol_key) else None,
        "note": note_t.string(note_key, ""),
    }


def _check_label(
    table: Table, name: str, fig: PublishedFigure, peak: float | None
) -> PublishedFigure:
    if (
        peak
        and fig.evidence == "prediction"
        and restates_peak(fig.metric, fig.value, fig.scenario, peak)
    ):
        raise table.error(
            name,
            f"{fig.value:g} is the file's pipelines x clock ({peak:g} samples/s) restated, "
            "not a prediction",
            "peak or fitted",
        )
    return fig


def _measured(
    t: Table, keys: set[str], arch_keys: set[str] | None, peak: float | None
) -> PublishedFigure:
    name = t.string("name")
    if not _NAME.match(name):
        raise t.error("name", f"invalid {name!r}", "lowercase letters, digits, _ . -")
    if name in keys:
        raise t.error("name", f"{name!r} is already a figure of this file", "a new name")
    given = [m for m in METRICS if t.has(m)]
    if len(given) != 1:
        raise t.error("fps", f"give exactly one of {', '.join(METRICS)}", "one")
    metric = given[0]
    hi = 1.0 if metric == "cache_hit_rate" else None
    value = t.number(metric, lo=0.0, hi=hi, lo_open=True)
    volume = tuple(int(v) for v in t.vector("volume", 3, lo=2, hi=1 << 12))
    if any(float(v) != int(v) for v in t.data["volume"]) or len(set(volume)) != 1:
        raise t.error("volume", f"invalid {t.data['volume']!r}", "[n, n, n] whole voxels")
    image = t.raw("image", None)
    if image is not None:
        image = tuple(int(v) for v in t.vector("image", 2, lo=1, hi=1 << 13))
    scenario = Scenario(
        volume=volume,  # type: ignore[arg-type]
        image=image,  # type: ignore[arg-type]
        supersampling=t.number("supersampling", 1.0, 0.125, 16.0),
        early_termination=t.number("early_termination", 1.0, 0.0, 1.0, lo_open=True),
        mode=t.choice("mode", ("composite", "mip"), "composite"),
        view=t.vector("view", 2, [0.0, 0.0], -360.0, 360.0),  # type: ignore[arg-type]
        projection=t.choice("projection", ("parallel", "perspective"), "parallel"),
        description=t.string("scenario", ""),
    )
    evidence = t.choice("evidence", EVIDENCE, "prediction")
    fig = PublishedFigure(
        key=name,
        value=value,
        metric=metric,
        scenario=scenario,
        evidence=evidence,
        **_labels(evidence, arch_keys, (t, "fitted_from"), (t, "tolerance"), (t, "note")),
        source=t.string("source"),
        kind=t.choice("kind", ("measured", "simulated", "stated")),
    )
    t.finish()
    return _check_label(t, "evidence", fig, peak)


def parse_published(
    data: Any,
    *,
    source: str,
    peak_samples_per_second: float | None = None,
    arch_data: dict[str, Any] | None = None,
) -> list[PublishedFigure]:
    """The figures of a ``[published]`` table, in file order (headline keys, then the
    ``[[published.measured]]`` entries).

    Every figure must carry ``evidence``; a bad label, an unknown ``fitted_from`` key
    (checked against ``arch_data``, the whole file, when given) or a prediction that
    restates ``peak_samples_per_second`` raises :class:`InputError` naming the key.
    """
    top = Table(data, source, "published")
    tolerance = top.table("tolerance")
    notes = top.table("notes")
    evidence_t = top.table("evidence")
    fitted_t = top.table("fitted_from")
    arch_keys = _keys_in(arch_data) if arch_data is not None else None
    headline = [
        k
        for k, v in top.data.items()
        if k not in ("tolerance", "notes", "evidence", "fitted_from", "measured")
    ]
    sizes = [int(m.group(2)) for k in headline if (m := _HEADLINE.match(k))]
    out: list[PublishedFigure] = []
    for key in headline:
        parsed = _headline_scenario(key, sizes)
        if key == "voxels_per_axis":  # a fact beside the figures, not a figure
            top.integer(key, lo=1, hi=1 << 16)
            continue
        if parsed is None:
            raise top.error(key, "unknown figure", "fps_N, seconds_N, samples_per_second")
        metric, scenario = parsed
        value = top.number(key, lo=0.0, lo_open=True)
        evidence = evidence_t.choice(key, EVIDENCE)
        labels = _labels(evidence, arch_keys, (fitted_t, key), (tolerance, key), (notes, key))
        fig = PublishedFigure(
            key=key, value=value, metric=metric, scenario=scenario, evidence=evidence, **labels
        )
        out.append(_check_label(evidence_t, key, fig, peak_samples_per_second))
    keys = {f.key for f in out}
    for t in top.tables("measured"):
        fig = _measured(t, keys, arch_keys, peak_samples_per_second)
        keys.add(fig.key)
        out.append(fig)
    for t in (tolerance, notes, evidence_t, fitted_t):
        t.finish()  # a label for a figure the file does not have is a typo
    top.finish()
    return out
