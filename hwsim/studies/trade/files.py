"""Trade tables: CSV and JSON with the same rows, and their printed cells."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

from hwsim.core.paths import atomic_write, write_text_atomic
from hwsim.numerics import EXACT_MATCHES, ROUND_OFF

__all__ = ["write_rows", "fmt_cell", "psnr_cell", "EXACT_LEGEND"]

#: The legend of the PSNR columns, shared by the printed table and the report.
EXACT_LEGEND = (
    "exact: identical images, or a difference within float64 round-off "
    f"(max abs error <= {ROUND_OFF:g} of the peak; the *_match columns say which)"
)


def fmt_cell(value: Any, spec: str, width: int = 0) -> str:
    """One right-aligned table cell: ``-`` when not measured, ``exact`` for infinity."""
    if value is None:
        return f"{'-':>{width}}"
    if isinstance(value, float) and value == float("inf"):
        return f"{'exact':>{width}}"
    return f"{value:>{width}{spec}}"


def psnr_cell(row: dict[str, Any], prefix: str, width: int = 0) -> str:
    """A PSNR column: ``exact`` when the images are identical or differ only by float64
    round-off (the ``*_match`` column says which), else the dB value."""
    if row.get(f"{prefix}_match") in EXACT_MATCHES:
        return f"{'exact':>{width}}"
    return fmt_cell(row[f"{prefix}_psnr_db"], ".1f", width)


def write_rows(
    rows: list[dict[str, Any]], csv_path: Path | None, json_path: Path | None, **extra: Any
) -> None:
    """``rows`` as CSV (lists joined with ``;``) and as JSON ``{"schema": 1, "rows": ...}``.

    Either path may be ``None`` to skip that file; ``extra`` keys go into the JSON.

    Infinite values (PSNR of identical images) are ``inf`` in the CSV and ``null`` in the
    JSON, which has no infinity.
    """
    if csv_path is not None:
        fields = list(dict.fromkeys(k for r in rows for k in r))
        with atomic_write(csv_path) as tmp, open(tmp, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=fields)
            writer.writeheader()
            for r in rows:
                writer.writerow(
                    {k: ";".join(map(str, v)) if isinstance(v, list) else v for k, v in r.items()}
                )
        if json_path is None:
            return

    def finite(v: Any) -> Any:
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {k: finite(x) for k, x in v.items()}
        return v

    body = {"schema": 1, **extra, "rows": [finite(r) for r in rows]}
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(body, indent=2) + "\n")
