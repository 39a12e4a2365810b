"""The skew proofs: VolumePro's two-level mini-block skew keeps every module's bursts
back-to-back for every principal axis; layouts without the bank level stall.

# Ref: architectures.md section 3 (US 6,266,733: mini-blocks skewed across modules and
#      banks so "bursts never stall", near 100 % efficiency [V abstract]) and 9.5 item 2.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.memory import MemoryConfig, SdramConfig, parse_memory, schedule_bursts, simulate_events
from hwsim.run.fidelity import resolve_arch
from models.memory_streams import module_streams, processing_order

pytestmark = pytest.mark.model

AXES = ["x", "y", "z"]


def vp500() -> MemoryConfig:
    arch = resolve_arch("volumepro500")
    return parse_memory(arch.memory, source=arch.source)


def without_refresh(mem: MemoryConfig) -> MemoryConfig:
    return dataclasses.replace(mem, sdram=dataclasses.replace(mem.sdram, t_refi=0))


def assert_back_to_back_but_for_refresh(mem: MemoryConfig, sched) -> None:
    """Every data-bus gap after the first burst comes right after a refresh and is exactly
    tRP + tRFC + tRCD (precharge-all, refresh, re-activate); nothing else ever waits."""
    d = mem.sdram
    st = sched.stats
    assert st.stall_bank_cycles == 0 and st.stall_arrival_cycles == 0
    gaps = np.diff(sched.read) - d.burst_cycles
    stalled = gaps[gaps > 0]
    assert stalled.size == st.refreshes
    assert np.all(stalled == d.t_rp + d.t_rfc + d.t_rcd)
    assert st.elapsed_cycles == (
        st.data_busy_cycles + st.first_access_cycles + st.refreshes * (d.t_rp + d.t_rfc + d.t_rcd)
    )


@pytest.mark.parametrize("n", [32, 64, 96])
@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("axis", AXES)
def test_vp500_bursts_are_back_to_back_on_every_axis(axis, reverse, n):
    """Front to back and back to front: each module reads n^3 / (8 M) mini-blocks, and
    only refresh ever opens a gap on its data bus.  Sizes whose mini-block count per axis
    is a multiple of modules x banks (n = 32 k; docs/memory.md says what other sizes
    cost)."""
    mem = vp500()
    streams = module_streams(mem, n, axis, reverse=reverse)
    assert [len(s) for s in streams] == [n**3 // 8 // mem.modules] * mem.modules
    for s in streams:
        assert_back_to_back_but_for_refresh(mem, schedule_bursts(mem.sdram, s.bank, s.row))


@pytest.mark.parametrize("axis", AXES)
def test_vp500_without_refresh_is_exactly_100_percent(axis):
    """Refresh off: after the first access latency the data bus never idles."""
    mem = without_refresh(vp500())
    for s in module_streams(mem, 64, axis):
        st = schedule_bursts(mem.sdram, s.bank, s.row).stats
        assert st.streaming_efficiency == 1.0
        assert st.row_conflicts > 0 or st.row_misses > 0  # rows do change: banks hide it


@pytest.mark.parametrize("axis", AXES)
def test_vp500_256_cubed_slice_sweep(axis):
    """One mini-block slab (two slices) of a 256^3 volume: 16 384 mini-blocks."""
    mem = vp500()
    for s in module_streams(mem, 256, axis, slabs=1):
        assert len(s) == 128 * 128 // mem.modules
        assert_back_to_back_but_for_refresh(mem, schedule_bursts(mem.sdram, s.bank, s.row))


@pytest.mark.slow
@pytest.mark.parametrize("axis", AXES)
def test_vp500_256_cubed_full_frame(axis):
    """A whole 256^3 frame (524 288 bursts per module), module 0."""
    mem = vp500()
    s = module_streams(mem, 256, axis)[0]
    sched = schedule_bursts(mem.sdram, s.bank, s.row)
    assert_back_to_back_but_for_refresh(mem, sched)
    assert sched.stats.efficiency > 0.98  # 98.66 %: 13 of every ~976 cycles refresh


def test_mini_block_streams_cover_each_word_once():
    """Every module's stream reads distinct, burst-aligned addresses: one frame reads each
    stored mini-block exactly once."""
    mem = vp500()
    for s in module_streams(mem, 32, "y"):
        key = (s.bank * mem.sdram.rows + s.row) * mem.sdram.columns + s.column
        assert np.unique(key).size == len(s)
        assert np.all(s.column % mem.sdram.burst_length == 0)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_without_bank_skew_bursts_stall(axis):
    """The contrast: the same module skew with banks from the high address bits.  Across
    the slices the next mini-block of a module is in another row of the *same* bank, so
    the precharge and activate cannot hide behind another bank's burst."""
    mem = dataclasses.replace(vp500(), skew="block")
    for s in module_streams(mem, 64, axis):
        st = schedule_bursts(mem.sdram, s.bank, s.row).stats
        assert st.stall_bank_cycles > 0.2 * st.data_busy_cycles
        assert st.efficiency < 0.85


def test_without_bank_skew_the_z_axis_still_streams():
    """Along z consecutive mini-blocks of a module are consecutive addresses: mostly row
    hits, so only the page crossings stall."""
    mem = dataclasses.replace(vp500(), skew="block")
    s = module_streams(mem, 64, "z")[0]
    st = schedule_bursts(mem.sdram, s.bank, s.row).stats
    assert 0 < st.stall_bank_cycles < 0.05 * st.data_busy_cycles


def test_cube4_single_voxel_skew_on_sdram():
    """Cube-4's skew puts one voxel per module per clock: on SDRAM that is a burst of one
    word.  Along z (beams along x) a module's voxels are consecutive words, but along y a
    module jumps a whole slice per voxel: every access opens a row in the same bank."""
    mem = MemoryConfig(modules=4, skew="cube4", sdram=SdramConfig(burst_length=1))
    eff = {}
    for axis in AXES:
        s = module_streams(mem, 32, axis)[0]
        eff[axis] = schedule_bursts(mem.sdram, s.bank, s.row).stats.efficiency
    assert eff["z"] > 0.9
    assert eff["y"] < 0.5


def test_simpy_form_agrees_on_the_vp500_stream():
    mem = vp500()
    s = module_streams(mem, 32, "x")[1]
    cycle = schedule_bursts(mem.sdram, s.bank, s.row)
    events = simulate_events(mem.sdram, s.bank, s.row)
    assert np.array_equal(cycle.data_end, events.data_end) and cycle.stats == events.stats


def test_processing_order_is_slice_then_beam():
    """architectures.md 6.3: x-major slices walk (i, j, k) = (y, z, x), i fastest."""
    x, y, z = processing_order(3, "x")
    assert (x[:4].tolist(), y[:4].tolist(), z[:4].tolist()) == ([0] * 4, [0, 1, 2, 0], [0, 0, 0, 1])
    x, y, z = processing_order(2, "z", reverse=True)
    assert z[0] == 1 and x[:2].tolist() == [0, 1]
    with pytest.raises(ValueError, match="axis"):
        processing_order(2, "w")
