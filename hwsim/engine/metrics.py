"""Derived metrics from raw counters, computed here and nowhere else (conventions item 7)."""

from __future__ import annotations

from typing import Any

__all__ = ["derive", "issued_samples"]


def derive(
    counters: dict[str, int], *, cycles: int, samples: int, pipelines: int, clock_hz: float
) -> dict[str, Any]:
    """Samples per cycle, utilisation per unit and lane, frame time and rate at ``clock_hz``.

    ``utilisation`` of ``pipeline[i].<unit>`` is ``busy_cycles / cycles``; ``stall_share``
    is ``stall_cycles / cycles``; ``hit_rates[<cache>]`` is ``<cache>.hits /
    <cache>.lookups``.
    """
    out: dict[str, Any] = {
        "samples_per_cycle": samples / cycles if cycles else 0.0,
        "peak_samples_per_cycle": pipelines,
        "efficiency": samples / (cycles * pipelines) if cycles else 0.0,
        "frame_seconds": cycles / clock_hz,
        "frames_per_second": clock_hz / cycles if cycles else 0.0,
    }
    units: dict[str, dict[str, float]] = {}
    for path, value in counters.items():
        if path.endswith(".busy_cycles") or path.endswith(".stall_cycles"):
            unit, _, kind = path.rpartition(".")
            entry = units.setdefault(unit, {})
            key = "utilisation" if kind == "busy_cycles" else "stall_share"
            entry[key] = value / cycles if cycles else 0.0
    out["units"] = units
    # Caches: ``<cache>.hits`` / ``<cache>.lookups``.
    out["hit_rates"] = {
        path[: -len(".hits")]: value / counters[path[: -len("hits")] + "lookups"]
        for path, value in counters.items()
        if path.endswith(".hits") and counters.get(path[: -len("hits")] + "lookups")
    }
    return out


def issued_samples(counters: dict[str, int], samples: int) -> int:
    """The samples the machine issued: ``frame.issued_samples`` where it leaps empty space
    or ends rays early (VIZARD II), else ``samples`` (every sample of the frame).  A
    simulator's samples per second are counted on these: a frame's ``samples`` are its
    planned samples on every rung, and a leaped sample costs the simulator nothing."""
    return int(counters.get("frame.issued_samples", samples))
