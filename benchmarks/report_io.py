"""Shared by the benchmark scripts: timing a call, writing the JSON report."""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path
from typing import Any

from hwsim.core.paths import display_text

__all__ = ["median_seconds", "write_report"]


def write_report(report: dict[str, Any], path: Path | None) -> None:
    """Write ``report`` to ``path`` (parents created) and say so; nothing when None.

    Paths in it (a note naming a machine file or the shared data) are written relative to
    the repository (hwsim.core.paths.display_text), never as this machine's absolute paths.
    """
    if path is None:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(display_text(json.dumps(report, indent=2)) + "\n")
    print(f"wrote {path}")


def median_seconds(repeats: int, fn, *args, **kwargs) -> tuple[float, Any]:
    """Median wall seconds of ``repeats`` calls after one warm-up call, and the last result."""
    fn(*args, **kwargs)
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn(*args, **kwargs)
        times.append(time.perf_counter() - start)
    return statistics.median(times), result
