"""The cycle rung's SDRAM command streams replayed through the datasheet checker (rtl/sdram).

Every view and mode of the RTL-top cosim cases (tests/rtl/top_cases.py), rendered on
VolumePro 500 from a 64^3 head by the cycle rung with its waveform on: each of the four
modules' command buses is read back from the VCD and replayed, after the power-up
sequence, through ``sdram_checker`` on Verilator (one case also on Icarus).  Every
command must be legal, and the checker's counts must equal the cycle rung's own
counters (per-module bursts; activations, precharges and refreshes summed).
"""

from __future__ import annotations

import pytest
from simulators import require
from top_cases import LIT_CASES, TOP_CASES, scene_of

from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from rtl.sdram.replay import check_vcd, device_of

pytestmark = pytest.mark.cosim
ARCH = "volumepro500"
SIZE = 64
#: The cosim cases' views and modes (their archs and sizes are Cube-4's), once each.
VIEWS = sorted({(az, el, mode) for _, az, el, mode, _ in TOP_CASES + LIT_CASES})
CASES = [(*view, "verilator") for view in VIEWS] + [(*VIEWS[0], "icarus")]


def cycle_frame(az, el, mode, vcd):
    volume = make_phantom("head", size=SIZE)
    scene = scene_of(az, el, mode, image=SIZE)
    machine = resolve_arch(ARCH)
    transfer = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    return render_cycle(frame_of(scene, volume, transfer, machine, plan), trace=vcd)


@pytest.mark.parametrize(("az", "el", "mode", "sim"), CASES)
def test_the_cycle_rungs_commands_are_legal_and_counted_alike(az, el, mode, sim, tmp_path):
    require(sim)
    vcd = tmp_path / "frame.vcd"
    result = cycle_frame(az, el, mode, vcd)
    counters = result.counters
    replays = check_vcd(vcd, device_of(ARCH), sim)
    assert len(replays) == 4
    for k, got in enumerate(replays):
        assert got.counts["violations"] == 0, got.violations[:5]
        assert got.counts["reads"] == counters[f"memory.module[{k}].bursts"]
        assert got.counts["writes"] == 0
    for name in ("activates", "precharges", "refreshes"):
        assert sum(r.counts[name] for r in replays) == counters[f"memory.sdram.{name}"], name
    assert counters["memory.sdram.refreshes"] > 0  # the frames are long enough to refresh
    assert counters["memory.sdram.row_conflicts"] > 0  # and close rows to open others
