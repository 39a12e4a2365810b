"""The shape of ``stats.json``: what :func:`hwsim.run.output.stats_dict` writes and
``hwsim report`` reads back, declared once.

The model names every key the report's tables and plots read, with its type and whether
it may be absent or null; a render's ``stats.json`` is checked against it by the report
at load (:func:`hwsim.report.inputs.read_stats`) and by the tests for every rung's real
output (tests/report/test_stats_schema.py), so what is written and what is read cannot
drift apart.  A sweep database's ``stats`` column holds the same document.

Conventions (as the report reads each key): a key read with ``[...]`` is required, null
allowed where a run may not have measured it (``T | None`` without a default); a key read
with ``.get(key)`` may be absent or null (``T | None = None``); a table or list read with
``.get(key, default)`` may be absent but never null (``= {}`` or ``= []``).  Numbers are any
JSON number (``float``: NaN and infinities included, as Python's JSON writes them);
unknown keys are ignored (:class:`hwsim.core.json_input.Recorded`).
"""

from __future__ import annotations

from typing import Any

from hwsim.core.json_input import Recorded

__all__ = ["PricedStats", "Stats"]


class Synthesized(Recorded):
    """A unit's Yosys synthesis (hwsim.energy.synth)."""

    meets_clock: bool | None
    memory_bits: int
    logic_levels: int
    fmax_hz: float | None
    fmax_basis: str | None = None
    independence: str | None = None
    table_logic_mm2: float | None = None
    logic_mm2: float | None = None
    storage_mm2: float | None = None
    logic_table_over_synthesized: float | None = None
    table_storage_bits: int | None = None


class Joules(Recorded):
    joules: float


class SquareMm(Recorded):
    mm2: float


class Energy(Recorded):
    """Energy per frame (hwsim.energy)."""

    total_joules: float | None
    dynamic_joules: float | None
    per_sample_joules: float | None
    static_joules: float | None
    average_watts: float | None
    units: dict[str, Joules] = {}
    memories: dict[str, Joules] = {}


class Fpga(Recorded):
    """A unit placed and routed on an ECP5 (hwsim.energy.fpga): the third way."""

    fmax_hz: float
    luts: int
    ffs: int
    dsps: int
    brams: int
    meets_clock: bool | None
    basis: str | None = None


class UnitArea(Recorded):
    mm2: float
    synthesized: Synthesized | None = None
    fpga: Fpga | None = None
    rtl_differs: str | None = None


class Area(Recorded):
    """Silicon area (hwsim.energy)."""

    total_mm2: float | None
    per_pipeline_mm2: float | None
    gate_equivalents: float | None
    units: dict[str, UnitArea]
    buffers: dict[str, SquareMm] = {}


class Band(Recorded):
    """One band of rays of a frame split across workers (hwsim.run.frame_split)."""

    band: int
    rays: int
    samples: int
    rows: int
    peak_rss_bytes: int
    seconds: float
    host: str


class Split(Recorded):
    bands: list[Band]
    workers: int
    driver_peak_rss_bytes: int


class SceneRender(Recorded):
    mode: str


class SceneVolume(Recorded):
    path: str | None = None


class RecordedScene(Recorded):
    """The scene as rendered (:meth:`hwsim.spec.scene.Scene.to_dict`); the report parses
    it again as a scene (its keys are then the scene model's)."""

    render: SceneRender
    name: str | None = None
    source: str = "<stats.json>"
    volume: SceneVolume | None = None


class RecordedVolume(Recorded):
    name: str
    shape_zyx: list[int]
    dtype: str


class TechnologyRecord(Recorded):
    """The node energy and area are priced in (:meth:`hwsim.energy.Technology.describe`)."""

    name: str
    node_nm: float
    vdd: float


class Stats(Recorded):
    """A render's ``stats.json``."""

    fidelity: str
    sampling: str
    arch: str | None
    scene: RecordedScene
    volume: RecordedVolume
    samples: int
    wall_seconds: float
    cycles: int | None = None
    clock_hz: float | None = None
    frame_seconds: float | None = None
    frames_per_second: float | None = None
    samples_per_second: float | None = None
    host_seconds: float | None = None
    machine_frame_seconds: float | None = None
    elaborated_units: list[str] = []
    elided_units: list[str] = []
    counters: dict[str, Any] = {}
    technology: TechnologyRecord | None = None
    energy: Energy | None = None
    area: Area | None = None
    split: Split | None = None


class PricedStats(Recorded):
    """A run with energy and area states the technology and clock they were priced at."""

    technology: TechnologyRecord
    clock_hz: float
