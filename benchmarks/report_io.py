"""What every benchmark script does with its report: write it as JSON when asked."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = ["write_report"]


def write_report(report: dict[str, Any], path: Path | None) -> None:
    """Write ``report`` to ``path`` (parents created) and say so; nothing when None."""
    if path is None:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=2) + "\n")
    print(f"wrote {path}")
