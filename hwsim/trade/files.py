"""Writing trade tables: CSV and JSON with the same rows."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

__all__ = ["write_rows"]


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
        with open(csv_path, "w", newline="") as fh:
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
        json_path.write_text(json.dumps(body, indent=2) + "\n")
