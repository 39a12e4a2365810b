"""The ladder trade's table: printed fixed-width, and as ``trade.md``, each empty or
what-if cell marked ``[n]`` with its one-line reason listed under the table, and the cells
left out of the product listed once each.

# Ref: docs/sweeps.md ("The fidelity-ladder trade").
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hwsim.studies.trade.files import EXACT_LEGEND, fmt_cell, psnr_cell

__all__ = ["format_ladder", "ladder_markdown", "reason_lines", "marked_statuses"]

#: (header, width; 0: the last, unpadded column, "<": left-aligned) of the table.
_HEADER = (
    ("scene", -15),
    ("arch", -15),
    ("rung", -12),
    ("wall s", 8),
    ("Msamp/s", 9),
    ("cycles", 11),
    ("num PSNR", 9),
    ("alg PSNR", 9),
    ("cyc err", 8),
    ("status", 0),
)

COLUMN_LEGEND = (
    "num PSNR: against golden at the same sample positions; alg PSNR: golden at the "
    "machine's positions against the ideal ray caster; cyc err: against the cycle rung "
    "(shared: a consistency check, both rungs time the frame with the same functions, "
    "cycle_independence in the files names them; ref: the cycle rung itself); "
    "what-if: measured outside the machine's published features (--extend)"
)

NOT_RUN_HEAD = (
    "not run (left out: outside what the machine has, as published, or beyond a rung's "
    "limits; --extend measures the what-ifs; naming both --arch and --rungs makes each "
    "combination a row):"
)


def marked_statuses(rows: Sequence[dict[str, Any]]) -> tuple[list[str], list[str]]:
    """Each row's status with a ``[n]`` marker where it is not plain ``ok`` (what-if,
    unsupported, not available), and the footnotes ``[n] reason``, one per reason."""
    markers: dict[str, int] = {}
    statuses = []
    for r in rows:
        note = r.get("note") or ""
        if r["status"] == "ok" or not note:
            statuses.append(r["status"])
            continue
        n = markers.setdefault(note, len(markers) + 1)
        statuses.append(f"{r['status']} [{n}]")
    return statuses, [f"[{n}] {note}" for note, n in markers.items()]


def _cells(row: dict[str, Any], status: str) -> list[str]:
    sps = row["wall_samples_per_second"]
    return [
        row["scene"],
        row["arch"],
        row["rung"],
        fmt_cell(row["wall_seconds"], ".3f"),
        fmt_cell(sps / 1e6 if sps else None, ".2f"),
        fmt_cell(row["cycles"], ",d"),
        psnr_cell(row, "numerical"),
        psnr_cell(row, "algorithmic"),
        _cycle_error_cell(row),
        status,
    ]


def _cycle_error_cell(row: dict[str, Any]) -> str:
    """The ``cyc err`` cell: the error, or ``shared`` where both sides share the code
    that sets the count (no measurement), ``ref`` for the cycle rung itself."""
    independence = row.get("cycle_independence") or ""
    if independence == "reference":
        return "ref"
    if independence.startswith("shared"):
        return "shared"
    return fmt_cell(row.get("cycle_error"), ".1%")


def _widths(rows: Sequence[dict[str, Any]]) -> list[int]:
    """The columns' widths: the header's, the scene and arch columns widened to their
    longest name (never cut: two machines' names may share their first 14 letters)."""
    widths = [w for _, w in _HEADER]
    for column, key in ((0, "scene"), (1, "arch")):
        longest = max((len(r[key]) for r in rows), default=0)
        widths[column] = -max(-widths[column], longest + 1)
    return widths


def _fixed(cells: Sequence[str], widths: Sequence[int]) -> str:
    out = ""
    for text, width in zip(cells, widths, strict=True):
        if width == 0:
            out += f"  {text}"
        else:
            out += f"{text:<{-width}}" if width < 0 else f"{text:>{width}}"
    return out


def _notes(footnotes: list[str], not_run: Sequence[dict[str, Any]]) -> list[str]:
    lines = list(footnotes)
    if not_run:
        lines += [NOT_RUN_HEAD] + [f"  {e['text']}" for e in not_run]
    return lines


def format_ladder(rows: Sequence[dict[str, Any]], not_run: Sequence[dict[str, Any]] = ()) -> str:
    """The trade table as fixed-width text (one line per scene, machine and rung), the
    reasons of its marked cells, the cells not run and the legend."""
    statuses, footnotes = marked_statuses(rows)
    widths = _widths(rows)
    lines = [_fixed([h for h, _ in _HEADER], widths)]
    lines += [_fixed(_cells(r, s), widths) for r, s in zip(rows, statuses, strict=True)]
    lines += _notes(footnotes, not_run)
    lines += [COLUMN_LEGEND, EXACT_LEGEND]
    return "\n".join(lines)


def ladder_markdown(rows: Sequence[dict[str, Any]], not_run: Sequence[dict[str, Any]] = ()) -> str:
    """The trade table as Markdown (``trade.md``), with the same marks and notes."""
    statuses, footnotes = marked_statuses(rows)
    lines = ["# Fidelity-ladder trade", ""]
    lines.append("| " + " | ".join(h for h, _ in _HEADER) + " |")
    lines.append("|" + "|".join("---" if w <= 0 else "---:" for _, w in _HEADER) + "|")
    for r, s in zip(rows, statuses, strict=True):
        cells = [c.strip().replace("|", "\\|") for c in _cells(r, s)]
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    notes = _notes(footnotes, not_run)
    lines += [f"- {n.strip()}" if n.startswith("  ") else n + "\n" for n in notes]
    lines += ["", COLUMN_LEGEND + ".", "", EXACT_LEGEND + ".", ""]
    return "\n".join(lines)


def reason_lines(rows: Sequence[dict[str, Any]], not_run: Sequence[dict[str, Any]]) -> list[str]:
    """The footnotes and not-run lines, for the plot's legend."""
    _, footnotes = marked_statuses(rows)
    return _notes(footnotes, not_run)
