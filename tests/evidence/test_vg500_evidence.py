"""Evidence for the vg500 top (issue 35): mutations of the RTL alone that must make the
comparisons the rtl tests make fail.  The mutations are the top's own parameters, given
to the RTL only (the devices, the host's write and the cycle rung keep the arch file's),
and run on Amaranth's simulator in this process (no source copy: nothing else changes).

* an SDRAM timing in the RTL controller (tRCD one clock long): its READs leave the cycle
  rung's scheduler's clocks (tests/rtl/test_vg500_sdram.py's agreement), one clock short:
  the datasheet checker also flags it;
* one bank less in the RTL's skew: the words come from the wrong addresses, the image
  differs from the cycle rung's;
* a shallower slab buffer (the least the frame allows): the pipelines wait on the memory
  longer; the image stays, the cycles grow past the cycle rung's (its slice-FIFO rules
  3', 5', 8', models/machines/volumepro/fifo_timing.py, since issue 35), which the
  unmutated top equals.
"""

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "rtl"))

from test_vg500_sdram import device_words, run, schedule, slab_order

import hwsim
from hwsim.studies.rtl_diff import _frame
from models.backend import Backend
from models.cycle import render_cycle
from models.machines.volumepro.cycle import SlabMachine
from models.machines.volumepro.fifo_timing import slice_fifo_timing
from rtl.vg500.frame import prepare_vg500
from rtl.vg500.sdram_ctrl import SdramTiming
from rtl.vg500.sim import run_vg500_amaranth

pytestmark = [pytest.mark.evidence, pytest.mark.rtl]


@pytest.mark.parametrize(("t_rcd", "violates"), [(3, False), (1, True)])
def test_rtl_controller_t_rcd_off_by_one_leaves_the_schedulers_clocks(t_rcd, violates):
    datasheet = SdramTiming(t_refi=100)
    n = 12
    raw = np.random.default_rng(0).integers(0, 4096, size=(n, n, n))
    requests = slab_order(n, 2, datasheet)
    mutated = dataclasses.replace(datasheet, t_rcd=t_rcd)
    dev, got = run(mutated, requests, device_words(n, 2, datasheet, raw), device=datasheet)
    want = schedule(datasheet, requests, got["admit"])
    assert got["read"] != want.read.tolist()
    assert bool(dev.violations) is violates
    if violates:
        assert all("tRCD" in v for v in dev.violations)


@pytest.fixture(scope="module")
def mip_frame():
    scene = hwsim.load_scene(None, volume="head:size=8", view=(30, 20), image=8, mode="mip")
    frame = _frame(scene, "volumepro500", None)
    return frame, render_cycle(frame), prepare_vg500(frame)


def test_rtl_with_one_bank_less_is_seen_in_the_image():
    # 12^3: mini-block sums reach 15, bank (s div 4) mod 4 = 3 (at 8^3 they stay below 12,
    # where three banks and four agree: this mutation passed there).
    scene = hwsim.load_scene(None, volume="head:size=12", view=(30, 20), image=12, mode="mip")
    frame = _frame(scene, "volumepro500", None)
    cycle, program = render_cycle(frame), prepare_vg500(frame)
    mutated = dataclasses.replace(program, timing=dataclasses.replace(program.timing, banks=3))
    result, _ = run_vg500_amaranth(mutated)
    assert not np.array_equal(np.asarray(result.image), np.asarray(cycle.image))


def test_rtl_shallower_slab_buffer_is_seen_in_the_cycles(mip_frame):
    frame, cycle, program = mip_frame
    base, base_out = run_vg500_amaranth(program)
    c, n_u = program.inner.registers["c"], -(-program.inner.registers["n_a"] // 2)
    least = 4 * c * (n_u + 1)
    assert least < program.slab_entries
    mutated = dataclasses.replace(program, slab_entries=least)
    result, out = run_vg500_amaranth(mutated)
    assert np.array_equal(np.asarray(result.image), np.asarray(base.image))
    assert out["hold_cycles"] > base_out["hold_cycles"]
    assert result.cycles > base.cycles
    rules = slice_fifo_timing(SlabMachine(Backend(frame)))
    assert (base.cycles, base_out["hold_cycles"]) == (rules.cycles, rules.stall_cycles)
    assert result.cycles != rules.cycles
