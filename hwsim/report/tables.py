"""What the report's tables add to the numbers they are given: the unit of a published
figure's metric, and long notes moved out of a table into numbered footnotes so the table
fits the page.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "METRIC_UNITS",
    "NOT_RECORDED",
    "figure_units",
    "fmt_value",
    "footnoted",
    "loo_units",
    "merged_diffs",
    "unit_column",
]

#: The unit of each published figure metric (hwsim.spec.published.METRICS).
METRIC_UNITS = {
    "fps": "fps",
    "seconds": "s",
    "samples_per_second": "samples/s",
    "cache_hit_rate": "hits/lookups",
}


def unit_column(
    header: list[str], body: list[list[str]], metrics: list[str], after: str
) -> tuple[list[str], list[list[str]]]:
    """``header`` and ``body`` with a ``unit`` column after the column ``after``: each
    line's metric (``metrics``, one per line) as :data:`METRIC_UNITS` names it."""
    at = header.index(after) + 1
    out = [
        [*line[:at], METRIC_UNITS.get(metric, "-"), *line[at:]]
        for line, metric in zip(body, metrics, strict=True)
    ]
    return [*header[:at], "unit", *header[at:]], out


def figure_units(
    header: list[str], body: list[list[str]], rows: list[dict[str, Any]]
) -> tuple[list[str], list[list[str]]]:
    """The figures table (``hwsim.studies.figures_tables.table``: one line per machine and
    figure) with the unit of each line's figure after its name."""
    metric = {(r["arch"], r["figure"]): r.get("metric") or _metric_of(r["figure"]) for r in rows}
    arch, figure = header.index("machine"), header.index("figure")
    metrics = [metric.get((line[arch], line[figure]), "") for line in body]
    return unit_column(header, body, metrics, "figure")


def loo_units(
    header: list[str], body: list[list[str]], loo: list[dict[str, Any]]
) -> tuple[list[str], list[list[str]]]:
    """The leave-one-out table (``loo_table``: one line per entry of ``loo``) with the
    predicted figure's unit after it (the clocks carry theirs already)."""
    return unit_column(header, body, [_metric_of(d["figure"]) for d in loo], "predicted")


def _metric_of(key: str) -> str:
    """A figure key's metric: ``fps_256`` -> ``fps``, ``seconds_128`` -> ``seconds``."""
    head = key.split("_")[0]
    return head if head in ("fps", "seconds") else key


def footnoted(
    header: list[str], body: list[list[str]], column: str
) -> tuple[list[str], list[list[str]], list[str]]:
    """``column``'s long texts replaced by footnote marks (``[1]``, ``[2]``; one number per
    distinct text, in order of first use): ``(header, body, notes)``."""
    at = header.index(column)
    notes: list[str] = []
    out = []
    for line in body:
        text = line[at]
        if text and text not in notes:
            notes.append(text)
        mark = f"[{notes.index(text) + 1}]" if text else ""
        out.append([*line[:at], mark, *line[at + 1 :]])
    return header, out, notes


def merged_diffs(header: list[str], body: list[list[str]]) -> tuple[list[str], list[list[str]]]:
    """Each ``diff`` column folded into the rung column before it (``5.914 (-40.9%)``), so
    the figures table has one column per rung and fits a page."""
    keep = [i for i, name in enumerate(header) if name != "diff"]
    out = []
    for line in body:
        cells = list(line)
        for i, name in enumerate(header):
            if name == "diff" and cells[i]:
                cells[i - 1] = f"{cells[i - 1]} ({cells[i]})"
        out.append([cells[i] for i in keep])
    names = [f"{name} (diff)" if header[i + 1 : i + 2] == ["diff"] else name
             for i, name in enumerate(header)]  # fmt: skip
    return [names[i] for i in keep], out


#: A cell whose value the run did not record.
NOT_RECORDED = "not recorded"


def fmt_value(v: Any, spec: str = ".4g") -> str:
    """A table cell: ``None`` as not recorded, inf as exact, ints with separators."""
    if v is None:
        return NOT_RECORDED
    if isinstance(v, float):
        return "exact" if v == float("inf") else format(v, spec)
    if isinstance(v, int):
        return f"{v:,}"
    return str(v)
