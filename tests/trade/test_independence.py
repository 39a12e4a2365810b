"""hwsim.studies.trade.independence: every comparison names real code, and the Cube-4 verdict
("shared") still describes what the two rungs import."""

from __future__ import annotations

import importlib

import pytest

from hwsim.run.fidelity import resolve_arch
from hwsim.studies.trade.independence import (
    CYCLE_ESTIMATE_VS_CYCLE,
    INDEPENDENT,
    RTL_VS_CYCLE,
    SHARED,
    TRANSACTION_VS_CYCLE,
    Comparison,
    cycle_comparison,
    shown_error,
    transaction_family,
)

COMPARISONS = [*TRANSACTION_VS_CYCLE.values(), CYCLE_ESTIMATE_VS_CYCLE, RTL_VS_CYCLE]


def _resolve(dotted: str):
    """The object a dotted name names: the longest importable module, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            obj = getattr(obj, name)
        return obj
    raise ImportError(dotted)


@pytest.mark.parametrize("comparison", COMPARISONS, ids=lambda c: c.label[:40])
def test_every_shared_name_is_real_code(comparison):
    for entry in comparison.shared:
        dotted = entry.partition(" (")[0]
        if "*" in dotted:  # every unit's constant: check one
            dotted = dotted.replace("*", "interp")
        assert _resolve(dotted) is not None, entry
    assert set(comparison.own) == set(comparison.sides)


def test_cube4s_rungs_share_their_timing_functions():
    """The verdict ``shared`` holds while both rungs' modules hold the same objects."""
    txn = importlib.import_module("models.machines.cube4.transaction")
    cyc = importlib.import_module("models.machines.cube4.cycle")
    for name in ("cube4_latency", "cube4_pixel_pushes", "cube4_lanes", "freezing_fifo"):
        assert getattr(txn, name) is getattr(cyc, name), name
    assert TRANSACTION_VS_CYCLE["cube4"].verdict == SHARED


def test_families_and_what_the_table_shows():
    assert transaction_family(resolve_arch("cube4-teramac")) == "cube4"
    assert transaction_family(resolve_arch("em-cube")) == "volumepro"
    assert transaction_family(resolve_arch("volumepro1000")) == "volumepro-skipping"
    assert transaction_family(resolve_arch("vizard2")) == "vizard2"
    cube4 = TRANSACTION_VS_CYCLE["cube4"]
    assert shown_error(cube4, 0.0) == (
        "consistency check (shared code: cube4_latency, cube4_pixel_pushes, freezing_fifo, "
        "cube4_lanes, cube4_buffers)"
    )
    assert shown_error(TRANSACTION_VS_CYCLE["vizard2-event-model"], -0.0137) == "-1.370%"
    assert shown_error(TRANSACTION_VS_CYCLE["vizard2"], 0.0012) == "+0.120%"  # packet model
    assert shown_error(TRANSACTION_VS_CYCLE["vizard2-shared-loop"], 0.0).startswith(
        "consistency check"
    )
    assert cycle_comparison("cycle", resolve_arch("cube4")) is None
    assert cycle_comparison("rtl", resolve_arch("cube4")) is RTL_VS_CYCLE
    with pytest.raises(ValueError, match="names what is shared"):
        Comparison(("a", "b"), "cycles", SHARED)
    assert Comparison(("a", "b"), "cycles", INDEPENDENT).label == "independent"
