"""What ``hwsim report`` reads, declared once per file kind and checked at load.

Every key the report's tables and plots read is in these msgspec models
(:class:`hwsim.core.json_input.Recorded`: keys a newer hwsim adds are ignored, a declared
key of the wrong type is refused): a hand-edited, truncated or foreign ``stats.json``,
``trade.json``, ``figures.json``, ``sweep.json`` or sweep database is one line naming the
file and the key path before any plot is drawn, never a ``KeyError`` in the middle of the
report.  ``stats.json``'s model is the writer's (:mod:`hwsim.run.stats_schema`).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.json_input import Recorded, read_json
from hwsim.core.models import validate
from hwsim.core.paths import file_kind, input_file
from hwsim.run.stats_schema import PricedStats, Stats

__all__ = [
    "Figures",
    "Stats",
    "SweepFacts",
    "SweepRow",
    "Trade",
    "read_figures",
    "read_image",
    "read_stats",
    "read_sweep_facts",
    "read_sweep_rows",
    "read_trade",
]


class TradeRow(Recorded):
    scene: str
    arch: str
    rung: str
    status: str
    wall_seconds: float | None
    wall_samples_per_second: float | None
    cycles: int | None
    numerical_psnr_db: float | None
    algorithmic_psnr_db: float | None
    numerical_match: str | None = None
    algorithmic_match: str | None = None
    cycle_error: float | None = None
    cycle_reference: str | None = None


class Trade(Recorded):
    """``trade.json`` (hwsim.studies.trade)."""

    rows: list[TradeRow]


class FigureRow(Recorded):
    arch: str
    figure: str
    rung: str
    status: str
    note: str
    published: float
    tolerance: float | None
    within: bool | None
    simulated: float | None
    difference: float | None
    evidence: str = ""
    scenario: str | None = None
    source: str | None = None
    kind: str | None = None
    metric: str | None = None
    fitted_from: list[str] | None = None
    size: int | None = None


class LeaveOneOutRow(Recorded):
    arch: str
    rung: str
    fitted_on: str
    fitted_evidence: str
    figure: str
    evidence: str
    clock_hz: float
    file_clock_hz: float
    published: float
    predicted: float
    difference: float


class Figures(Recorded):
    """``figures.json`` (hwsim figures)."""

    rows: list[FigureRow]
    machine: dict[str, str | float | None] | None = None
    evidence: str | None = None
    leave_one_out: list[LeaveOneOutRow] | None = None


class _Measured(Recorded):
    """A figure row measured ``ok`` states its simulated value and difference."""

    simulated: float
    difference: float


class _Sized(Recorded):
    """A figure row without a scenario states its size."""

    size: int


class SweepFacts(Recorded):
    """``sweep.json`` written beside a sweep's run (hwsim sweep --out)."""

    arch_overrides: dict[str, Any]


class SweepRow(Recorded):
    """A row of a sweep database (hwsim.studies.sweep.db) as the report's sweep table reads
    it, its JSON columns decoded: ``params`` and ``stats`` (the run's ``stats.json``)."""

    label: str | None
    status: str
    cycles: int | None
    frame_seconds: float | None
    samples_per_second: float | None
    wall_seconds: float | None
    error: str | None
    includes_compile: int | None = None
    params: dict[str, Any] | None = None
    stats: Stats | None = None


def read_stats(path: Path) -> dict[str, Any]:
    """A run's ``stats.json``, checked against :class:`Stats`; a run with energy and
    area states the technology and clock they were priced at."""
    stats = read_json(path, Stats)
    if stats.get("energy") and stats.get("area"):
        validate(stats, PricedStats, str(path))
    return stats


def read_trade(path: Path) -> dict[str, Any]:
    """``trade.json``, checked against :class:`Trade`."""
    return read_json(path, Trade)


def read_figures(path: Path) -> dict[str, Any]:
    """``figures.json``, checked against :class:`Figures`; a row measured ``ok`` states
    its simulated value and difference, a row without a scenario its size."""
    data = read_json(path, Figures)
    for i, row in enumerate(data["rows"]):
        if row["status"] == "ok":
            validate(row, _Measured, str(path), prefix=f"rows[{i}]")
        if not row.get("scenario"):
            validate(row, _Sized, str(path), prefix=f"rows[{i}]")
    return data


def read_sweep_facts(path: Path) -> dict[str, Any]:
    """``sweep.json`` beside a sweep's run: the architecture overrides it ran with."""
    return read_json(path, SweepFacts)["arch_overrides"]


def read_sweep_rows(path: Path) -> list[dict[str, Any]]:
    """The runs of a sweep database, sorted by their parameters, each checked against
    :class:`SweepRow`; a JSON column that does not parse is one line naming the file."""
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
    validate(rows, list[SweepRow], str(path), prefix="runs")
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
