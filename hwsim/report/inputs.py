"""What ``hwsim report`` reads, declared once per file kind and checked at load.

Every key the report's tables and plots read is in these shapes
(:mod:`hwsim.core.schema`): a hand-edited, truncated or foreign ``stats.json``,
``trade.json`` or ``figures.json`` is one line naming the file and the key path before
any plot is drawn, never a ``KeyError`` in the middle of the report.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.paths import file_kind, input_file
from hwsim.core.schema import MapOf, OneOf, Opt, check_shape, read_json

__all__ = [
    "FIGURES",
    "STATS",
    "SWEEP_FACTS",
    "TRADE",
    "read_figures",
    "read_image",
    "read_stats",
    "read_sweep_facts",
    "read_trade",
]

#: A number the report reads with ``.get`` (absent or null: "not recorded").
_NUM = Opt(float)
#: A number the report reads with ``[...]``: present, null when not measured.
_NULL_NUM = OneOf(float, None)
#: ``stats.json`` of a render (hwsim.run.output): what the report reads of it.
_SYNTHESIZED = {
    "meets_clock": OneOf(bool, None),
    "memory_bits": int,
    "logic_levels": int,
    "fmax_hz": _NULL_NUM,
    "fmax_basis": Opt(str),
    "independence": Opt(str),
    **{k: _NUM for k in ("table_logic_mm2", "logic_mm2", "storage_mm2")},
    "logic_table_over_synthesized": _NUM,
    "table_storage_bits": Opt(int),
}
_ENERGY = {
    **{k: _NULL_NUM for k in ("total_joules", "dynamic_joules", "per_sample_joules")},
    "static_joules": _NULL_NUM,
    "average_watts": _NULL_NUM,
    "units": Opt(MapOf({"joules": float}), null=False),
    "memories": Opt(MapOf({"joules": float}), null=False),
}
_AREA = {
    **{k: _NULL_NUM for k in ("total_mm2", "per_pipeline_mm2", "gate_equivalents")},
    "units": MapOf({"mm2": float, "synthesized": Opt(_SYNTHESIZED), "rtl_differs": Opt(str)}),
    "buffers": Opt(MapOf({"mm2": float}), null=False),
}
_BAND = {
    "band": int,
    **{k: int for k in ("rays", "samples", "rows", "peak_rss_bytes")},
    "seconds": float,
    "host": str,
}
STATS = {
    "fidelity": str,
    "sampling": str,
    "arch": OneOf(str, None),
    "scene": {
        "name": Opt(str),
        "source": Opt(str, null=False),
        "render": {"mode": str},
        "volume": Opt({"path": Opt(str)}),
    },
    "volume": {"name": str, "shape_zyx": [int], "dtype": str},
    "samples": int,
    "cycles": Opt(int),
    "wall_seconds": float,
    **{k: _NUM for k in ("clock_hz", "frame_seconds", "frames_per_second")},
    **{k: _NUM for k in ("samples_per_second", "host_seconds", "machine_frame_seconds")},
    "elaborated_units": Opt([str], null=False),
    "elided_units": Opt([str], null=False),
    "counters": Opt(dict, null=False),
    "technology": Opt({"name": str, "node_nm": float, "vdd": float}),
    "energy": Opt(_ENERGY),
    "area": Opt(_AREA),
    "split": Opt({"bands": [_BAND], "workers": int, "driver_peak_rss_bytes": int}),
}
_TRADE_ROW = {
    **{k: str for k in ("scene", "arch", "rung", "status")},
    "wall_seconds": _NULL_NUM,
    "wall_samples_per_second": _NULL_NUM,
    "cycles": OneOf(int, None),
    **{f"{p}_psnr_db": _NULL_NUM for p in ("numerical", "algorithmic")},
    **{f"{p}_match": Opt(str) for p in ("numerical", "algorithmic")},
    "cycle_error": _NUM,
    "cycle_reference": Opt(str),
}
#: ``trade.json`` (hwsim.studies.trade).
TRADE = {"rows": [_TRADE_ROW]}
_FIGURE_ROW = {
    **{k: str for k in ("arch", "figure", "rung", "status", "note")},
    "evidence": Opt(str, null=False),
    **{k: Opt(str) for k in ("scenario", "source", "kind", "metric")},
    "fitted_from": Opt([str]),
    "size": Opt(int),
    "published": float,
    "tolerance": _NULL_NUM,
    "within": OneOf(bool, None),
    "simulated": _NULL_NUM,
    "difference": _NULL_NUM,
}
_LOO_ROW = {
    **{k: str for k in ("arch", "rung", "fitted_on", "fitted_evidence", "figure", "evidence")},
    **{k: float for k in ("clock_hz", "file_clock_hz", "published", "predicted", "difference")},
}
#: ``sweep.json`` written beside a sweep's run (hwsim sweep --out).
SWEEP_FACTS = {"arch_overrides": MapOf(Any)}
#: ``figures.json`` (hwsim figures).
FIGURES = {
    "machine": Opt(MapOf(OneOf(str, float, None))),
    "evidence": Opt(str),
    "rows": [_FIGURE_ROW],
    "leave_one_out": Opt([_LOO_ROW]),
}


def read_stats(path: Path) -> dict[str, Any]:
    """A run's ``stats.json``, checked against :data:`STATS`; a run with energy and
    area states the technology and clock they were priced at."""
    stats = read_json(path, STATS)
    if stats.get("energy") and stats.get("area"):
        priced = {"technology": {"name": str, "node_nm": float, "vdd": float}, "clock_hz": float}
        check_shape(stats, priced, str(path))
    return stats


def read_trade(path: Path) -> dict[str, Any]:
    """``trade.json``, checked against :data:`TRADE`."""
    return read_json(path, TRADE)


def read_figures(path: Path) -> dict[str, Any]:
    """``figures.json``, checked against :data:`FIGURES`; a row measured ``ok`` states
    its simulated value and difference, a row without a scenario its size."""
    data = read_json(path, FIGURES)
    for i, row in enumerate(data["rows"]):
        if row["status"] == "ok":
            check_shape(row, {"simulated": float, "difference": float}, str(path), f"rows[{i}]")
        if not row.get("scenario"):
            check_shape(row, {"size": int}, str(path), f"rows[{i}]")
    return data


def read_sweep_facts(path: Path) -> dict[str, Any]:
    """``sweep.json`` beside a sweep's run: the architecture overrides it ran with."""
    return read_json(path, SWEEP_FACTS)["arch_overrides"]


#: A row of a sweep database (hwsim.studies.sweep.db) as the report's sweep table reads it.
SWEEP_ROW = {
    "label": OneOf(str, None),
    "status": str,
    "cycles": OneOf(int, None),
    **{k: _NULL_NUM for k in ("frame_seconds", "samples_per_second", "wall_seconds")},
    "includes_compile": Opt(int),
    "error": OneOf(str, None),
    "params": Opt(dict),
}


def read_sweep_rows(path: Path) -> list[dict[str, Any]]:
    """The runs of a sweep database, sorted by their parameters, each checked against
    :data:`SWEEP_ROW`; a JSON column that does not parse is one line naming the file."""
    import sqlite3

    from hwsim.studies.sweep.db import RunsDB, by_parameters

    try:
        with RunsDB(path, create=False) as db:
            rows = db.rows()
    except sqlite3.DatabaseError as exc:
        raise InputError(f"unreadable sweep database: {exc}", source=str(path)) from None
    except (ValueError, RecursionError):  # json.loads of the params or stats column
        raise InputError(
            "a params or stats column is not JSON", source=str(path), key="runs"
        ) from None
    for i, row in enumerate(rows):
        check_shape(row, SWEEP_ROW, str(path), f"runs[{i}]")
    return by_parameters(rows)


def read_image(path: Path) -> np.ndarray:
    """A run's ``image.npy``: a 2-D (gray) or 3-D (channels last) array of real numbers,
    not all NaN; anything else is one line naming the file."""
    if file_kind(path) not in (None, "a file"):  # a FIFO or a device: never opened
        input_file(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # NumPy's header warnings: the error says it
            image = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"unreadable image: {exc}", source=str(path)) from None
    allowed = "a (height, width) or (height, width, channels) array of numbers"
    if not isinstance(image, np.ndarray) or image.dtype.kind not in "biuf":
        raise InputError(
            f"not an array of numbers ({image.dtype})", source=str(path), allowed=allowed
        )
    if image.ndim not in (2, 3) or 0 in image.shape or (image.ndim == 3 and image.shape[2] > 4):
        raise InputError(
            f"shape {image.shape}", source=str(path), allowed=allowed + ", 1-4 channels"
        )
    if image.dtype.kind == "f" and not np.isfinite(image).all():
        bad = int(np.size(image) - np.isfinite(image).sum())
        raise InputError(f"{bad} NaN or infinite value(s)", source=str(path), allowed=allowed)
    return image
