"""SDRAM parameters shared by the cycle-exact and the SimPy forms of the memory model.

# Ref: shared/docs/reference/architectures.md section 9.1 (voxel memory controller: row
#      activate/precharge, CAS latency, burst length 8, refresh; VolumePro 500 needs
#      ~100 % burst efficiency [V US 6,266,733]) and 9.3 (CAS 2-3 clocks at 125 MHz,
#      PC100/PC133-class [I]).

One :class:`SdramConfig` describes one SDRAM device (one memory module: the chips that
share a command bus and a data bus).  All timings are in cycles of the *memory* clock;
``clock_ratio`` converts them to pipeline clocks.  A machine's ``[memory]`` table holds
the module count, the skew scheme and the device keys, flat::

    [memory]
    modules = 4
    skew = "miniblock"
    banks = 4
    cas_latency = 2
    ...

:data:`MemoryTable` is that table's model (built from :class:`SdramConfig`'s fields and
:data:`_RANGES`), :func:`parse_memory` validates it; every bad value raises
:class:`hwsim.core.errors.InputError` naming the file, the key (``memory.t_rcd``) and the
allowed range.  The model reads only (volume rendering never writes the volume during a
frame), so the write recovery ``t_wr`` is there for the SDRAM checker (rtl/sdram) only.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

import msgspec
import numpy as np

from hwsim.core.errors import InputError
from hwsim.core.models import Schema, between, integer, validate

__all__ = [
    "PAGE_POLICIES",
    "SKEWS",
    "MemoryConfig",
    "MemoryTable",
    "SdramConfig",
    "parse_memory",
]

#: ``open``: a row stays open after a read until a conflict or refresh closes it.
#: ``closed``: every read auto-precharges its bank (READ with auto-precharge).
PAGE_POLICIES = ("open", "closed")
#: Voxel layouts the request-stream generators know (models/memory_streams.py):
#: ``cube4`` one voxel per module, module ``(x+y+z) mod P``; ``miniblock`` VolumePro 500's
#: two-level mini-block skew (modules, then banks); ``block`` mini-blocks skewed across
#: modules only, banks taken from the high address bits (no bank skew).
SKEWS = ("cube4", "miniblock", "block")


@dataclass(frozen=True, kw_only=True)
class SdramConfig:
    """One SDRAM device (defaults: PC133-class 256 Mbit x16 at 125 MHz, CAS 2).

    Every timing is an integer number of memory-clock cycles.

    Parameters
    ----------
    banks : int
        Internal banks (4 in PC100/PC133 SDRAM).
    rows : int
        Rows per bank.
    columns : int
        Page size: words per row.
    word_bits : int
        Data-bus width (one word per beat).
    burst_length : int
        Words per READ burst.
    data_rate : int
        Beats per clock: 1 (SDR) or 2 (DDR).  A burst holds the data bus
        ``burst_length / data_rate`` cycles (:attr:`burst_cycles`).
    t_rcd : int
        ACTIVATE to READ of the same bank.
    cas_latency : int
        READ to the first data beat.
    t_rp : int
        PRECHARGE to ACTIVATE of the same bank.
    t_ras : int
        ACTIVATE to PRECHARGE of the same bank (row active time, minimum).
    t_rc : int
        ACTIVATE to ACTIVATE of the same bank (row cycle).
    t_rrd : int
        ACTIVATE to ACTIVATE of different banks.
    t_refi : int
        Average refresh interval: refresh ``k`` falls due at cycle ``k * t_refi``
        (0 disables refresh).
    t_rfc : int
        REFRESH to the next command (all banks idle meanwhile).
    t_wr : int
        Last write beat to PRECHARGE of the same bank (write recovery).  The model only
        reads; the SDRAM checker (rtl/sdram) holds writes to it.
    page_policy : str
        One of :data:`PAGE_POLICIES`.
    queue_depth : int
        Requests the controller holds: request ``i`` may issue commands once request
        ``i - queue_depth`` has issued its READ.  2 lets the next burst's PRECHARGE and
        ACTIVATE overlap the current burst (bank interleaving).
    clock_ratio : float
        Memory clock / pipeline clock (1.0: the same clock).
    """

    banks: int = 4
    rows: int = 8192
    columns: int = 512
    word_bits: int = 16
    burst_length: int = 8
    data_rate: int = 1
    t_rcd: int = 2
    cas_latency: int = 2
    t_rp: int = 2
    t_ras: int = 5
    t_rc: int = 8
    t_rrd: int = 2
    t_refi: int = 976
    t_rfc: int = 9
    t_wr: int = 2
    page_policy: str = "open"
    queue_depth: int = 2
    clock_ratio: float = 1.0

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            if f.name in _RANGES:
                lo, hi = _RANGES[f.name]
                value = getattr(self, f.name)
                if not lo <= value <= hi:
                    raise ValueError(f"{f.name} = {value} out of range {lo:g} .. {hi:g}")
        _check_consistency(
            dataclasses.asdict(self),
            lambda key, msg, allowed: ValueError(f"{key}: {msg} (allowed: {allowed})"),
        )

    @property
    def burst_cycles(self) -> int:
        """Cycles one burst holds the data bus: ``burst_length / data_rate``."""
        return self.burst_length // self.data_rate

    @property
    def read_to_precharge(self) -> int:
        """READ to PRECHARGE of the same bank without cutting the burst short.

        An SDR SDRAM may precharge ``CL - 1`` cycles before the last beat leaves, so the
        earliest PRECHARGE is ``READ + burst_cycles`` (JEDEC SDRAM read-with-precharge rule).
        """
        return self.burst_cycles

    @property
    def words(self) -> int:
        """Words in the device: banks x rows x columns."""
        return self.banks * self.rows * self.columns

    def to_pipeline_cycles(self, memory_cycles):
        """Memory-clock cycle counts or instants -> pipeline clocks, rounded up (the
        pipeline sees data at its first clock edge at or after the memory's)."""
        return np.ceil(np.asarray(memory_cycles) / self.clock_ratio).astype(np.int64)

    def to_memory_cycles(self, pipeline_cycles):
        """Pipeline-clock instants -> memory clocks, rounded up (e.g. a request's earliest
        issue cycle from the cycle its FIFO frees a slot)."""
        return np.ceil(np.asarray(pipeline_cycles) * self.clock_ratio).astype(np.int64)

    @property
    def peak_words_per_cycle(self) -> int:
        """Data beats per memory clock at 100 % bus use."""
        return self.data_rate


#: Allowed ranges (inclusive) of the numeric keys; also the ranges in error messages.
_RANGES: dict[str, tuple[float, float]] = {
    "banks": (1, 64),
    "rows": (1, 1 << 20),
    "columns": (1, 1 << 16),
    "word_bits": (1, 512),
    "burst_length": (1, 256),
    "data_rate": (1, 2),
    "t_rcd": (0, 64),
    "cas_latency": (1, 16),
    "t_rp": (0, 64),
    "t_ras": (0, 256),
    "t_rc": (0, 512),
    "t_rrd": (0, 64),
    "t_refi": (0, 1 << 20),
    "t_rfc": (0, 4096),
    "t_wr": (0, 64),
    "queue_depth": (1, 64),
    "clock_ratio": (1 / 64, 64),
}


def _check_consistency(v: dict[str, Any], error) -> None:
    """Cross-key rules on the values ``v``; ``error(key, message, allowed)`` builds the
    exception to raise."""
    if v["page_policy"] not in PAGE_POLICIES:
        raise error("page_policy", f"unknown value {v['page_policy']!r}", ", ".join(PAGE_POLICIES))
    burst_cycles = v["burst_length"] // v["data_rate"]
    if v["burst_length"] % v["data_rate"]:
        raise error("burst_length", f"{v['burst_length']} is odd with data_rate 2", "even")
    if v["columns"] % v["burst_length"]:
        raise error(
            "columns", f"{v['columns']} is not a multiple of burst_length", "k * burst_length"
        )
    if v["t_rc"] < v["t_ras"] + v["t_rp"]:
        raise error("t_rc", f"{v['t_rc']} < t_ras + t_rp", f">= {v['t_ras'] + v['t_rp']}")
    floor = v["t_rfc"] + v["t_rp"] + v["t_rc"] + burst_cycles
    if v["t_refi"] and v["t_refi"] <= floor:
        raise error(
            "t_refi",
            f"{v['t_refi']} leaves no time between refreshes",
            f"0 (off) or > t_rfc + t_rp + t_rc + burst cycles = {floor}",
        )


@dataclass(frozen=True, kw_only=True)
class MemoryConfig:
    """A machine's volume memory: ``modules`` independent SDRAM devices and a skew.

    Parameters
    ----------
    modules : int
        Memory modules, each one :class:`SdramConfig` device with its own buses.
    skew : str
        Voxel layout across modules and banks, one of :data:`SKEWS`.
    sdram : SdramConfig
        The device every module uses.
    """

    modules: int = 4
    skew: str = "miniblock"
    sdram: SdramConfig = field(default_factory=SdramConfig)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _memory_table() -> type[Schema]:
    """The model of a ``[memory]`` table: every :class:`SdramConfig` field with its
    default and :data:`_RANGES` range, the module count and the skew."""
    fields: list[tuple[str, Any, Any]] = []
    for f in dataclasses.fields(SdramConfig):
        if f.name == "page_policy":
            kind: Any = Literal[PAGE_POLICIES]  # type: ignore[valid-type]
        elif f.name == "clock_ratio":
            kind = between(*_RANGES[f.name])
        else:
            kind = integer(*(int(v) for v in _RANGES[f.name]))
        fields.append((f.name, kind, f.default))
    fields += [("modules", integer(1, 4096), 4), ("skew", Literal[SKEWS], "miniblock")]  # type: ignore[valid-type]
    return msgspec.defstruct("MemoryTable", fields, bases=(Schema,), module=__name__)


#: ``[memory]``: types, ranges and defaults of every key (:func:`parse_memory`).
MemoryTable = _memory_table()


def parse_memory(data: dict[str, Any], *, source: str) -> MemoryConfig:
    """Validate an architecture's ``[memory]`` table (``ArchConfig.memory``).

    Parameters
    ----------
    data : dict
        The raw table; missing keys take the :class:`SdramConfig` defaults.
    source : str
        The file the table came from (``ArchConfig.source``), for error messages.

    Returns
    -------
    MemoryConfig

    Raises
    ------
    hwsim.core.errors.InputError
        One line naming ``source``, ``memory.KEY`` and what is allowed: the types and
        ranges of :data:`MemoryTable`, then the rules across keys.
    """
    table = validate(data, MemoryTable, source, prefix="memory")
    values = {f.name: getattr(table, f.name) for f in dataclasses.fields(SdramConfig)}

    def error(key: str, message: str, allowed: str) -> InputError:
        return InputError(message, source=source, key=f"memory.{key}", allowed=allowed)

    _check_consistency(values, error)
    return MemoryConfig(modules=table.modules, skew=table.skew, sdram=SdramConfig(**values))
