"""The vg500's SDRAM controller RTL (rtl/vg500/sdram_ctrl.py) on Amaranth's simulator,
driving a stand-in device with a datasheet timing checker (tests/rtl/sdram_standin.py):
the words of a volume's slab order arrive intact and in order, no constraint is violated,
and the command cycles equal those of the cycle rung's scheduler (hwsim.memory's
SdramController) given the same requests admitted at the same clocks.

What the agreement is worth: the two share the device timings (the arch file's
``[memory]``) and the policy as docs/memory.md states it (in order, two requests held,
open pages, refresh when due); the RTL decides clock by clock from time stamps, the
scheduler computes each request's commands at once (hwsim/memory/sdram_kernel.py)."""

import numpy as np
import pytest
from amaranth.sim import Simulator
from sdram_standin import StandInSdram

from hwsim.memory import SdramConfig
from hwsim.memory import SdramController as Scheduler
from models.units.skew import vp500_miniblock
from rtl.vg500.sdram_ctrl import SdramController, SdramTiming, mode_register

pytestmark = pytest.mark.rtl


def slab_order(n: int, module: int, t: SdramTiming, M: int = 4):
    """``(bank, row, col)`` of module ``module``'s bursts in the slab order along z: slab
    after slab, mini-block beam after beam (pairs of y rows), mini-block along x."""
    out = []
    for slab in range(n // 2):
        for u in range(n // 2):
            for mb in range(n // 2):
                m, b, addr = vp500_miniblock(2 * mb, 2 * u, 2 * slab, n, M, t.banks)
                if int(m) == module:
                    out.append((int(b), int(addr) // t.columns, int(addr) % t.columns))
    return out


def device_words(n: int, module: int, t: SdramTiming, raw: np.ndarray, M: int = 4) -> dict:
    z, y, x = np.meshgrid(*(np.arange(n),) * 3, indexing="ij")
    m, b, addr = vp500_miniblock(x, y, z, n, M, t.banks)
    sel = m == module
    return {
        (int(bb), int(aa) // t.columns, int(aa) % t.columns): int(v)
        for bb, aa, v in zip(b[sel], addr[sel], raw[sel], strict=True)
    }


def run(
    t: SdramTiming, requests, words, *, gaps=(), max_clocks=200_000, device=None, restart_at=None
):
    """Run the controller on ``requests`` (offered back to back, except a request whose
    index is in ``gaps`` is held back 40 clocks); returns the device, the RTL's command
    log by ``now``, the admission clocks and the words read.  ``device``: the device's
    timing when the controller is given another (a mutation).  ``restart_at``: nothing is
    offered until that clock, where ``restart`` (a frame's start) is pulsed."""
    dut = SdramController(t, init_wait=4)
    dev = StandInSdram(device or t, words)  # device: the datasheet's, when the RTL's differs
    result = {"admit": [], "read": [], "activate": [], "precharge": [], "refresh": [], "words": []}

    async def bench(ctx):
        k, hold, clock = 0, 0, 0
        pending = set(gaps)
        while clock < max_clocks:
            if k < len(requests) and ctx.get(dut.ready) and hold == 0 and k in pending:
                hold = 40
                pending.discard(k)
            valid = k < len(requests) and hold == 0
            if restart_at is not None:
                ctx.set(dut.restart, clock == restart_at)
                valid = valid and clock > restart_at
            ctx.set(dut.req.valid, valid)
            if valid:
                bank, row, col = requests[k]
                ctx.set(dut.req.payload, {"bank": bank, "row": row, "col": col})
            ctx.set(dut.dq_in, dev.dq(clock))
            now = ctx.get(dut.now)
            if ctx.get(dut.ready):
                for name in ("read", "activate", "precharge", "refresh"):
                    if ctx.get(getattr(dut, f"cmd_{name}")):
                        result[name].append(now)
            if valid and ctx.get(dut.req.ready):
                result["admit"].append(now + 1)
                k += 1
            hold = max(hold - 1, 0)
            await ctx.tick()
            clock += 1
            pins = [ctx.get(getattr(dut, p)) for p in ("cs_n", "ras_n", "cas_n", "we_n", "ba", "a")]
            dev.sample(clock, *pins)
            if ctx.get(dut.rdata_valid):
                result["words"].append(ctx.get(dut.rdata_word))
            if len(result["words"]) == t.burst_length * len(requests):
                break
        result["clocks"] = clock

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    return dev, result


def schedule(t: SdramTiming, requests, admit):
    cfg = SdramConfig(
        **{k: getattr(t, k) for k in SdramTiming.__dataclass_fields__ if k != "word_bits"},
        word_bits=t.word_bits,
    )
    sched = Scheduler(cfg)
    sched.issue_many([r[0] for r in requests], [r[1] for r in requests], admit)
    return sched.schedule()


@pytest.mark.parametrize(
    ("n", "t_refi", "gaps"), [(16, 976, ()), (16, 100, ()), (12, 60, (5, 17, 30))]
)
def test_slab_order_reads_intact_legal_and_on_the_schedulers_clocks(n, t_refi, gaps):
    t = SdramTiming(t_refi=t_refi)
    raw = np.random.default_rng(n).integers(0, 4096, size=(n, n, n))
    requests = slab_order(n, 1, t)
    dev, got = run(t, requests, device_words(n, 1, t, raw), gaps=set(gaps))
    assert dev.violations == []
    assert dev.mode == mode_register(t.cas_latency, t.burst_length)
    want = [dev_words for r in requests for dev_words in _burst(device_words(n, 1, t, raw), r, t)]
    assert got["words"] == want
    sched = schedule(t, requests, got["admit"])
    assert got["read"] == sched.read.tolist()
    assert got["activate"] == [int(c) for c in sched.activate if c >= 0]
    last = sched.read[-1]
    refresh = sched.refresh
    assert [c for c in got["refresh"] if c < last] == refresh[:, 1].tolist()
    pres = sorted(
        [int(c) for c in sched.precharge if c >= 0] + [int(c) for c in refresh[:, 0] if c >= 0]
    )
    assert [c for c in got["precharge"] if c < last] == pres
    assert dev.counts["READ"] == len(requests)
    assert dev.counts["ACTIVATE"] == sched.stats.activates


def _burst(words, request, t):
    bank, row, col = request
    return [words.get((bank, row, col + j), 0) for j in range(t.burst_length)]


def test_a_frames_refreshes_are_counted_from_its_first_request():
    """Idle after power-up the controller refreshes as they fall due; a frame's start
    (``restart``) re-phases them: from its first request on, its commands are those of
    the scheduler whose clock 0 is that request's admission (the cycle rung's frame)."""
    n, t = 12, SdramTiming(t_refi=100)
    raw = np.random.default_rng(3).integers(0, 4096, size=(n, n, n))
    requests = slab_order(n, 2, t)
    dev, got = run(t, requests, device_words(n, 2, t, raw), restart_at=273)
    assert dev.violations == []
    first = got["admit"][0]
    assert len([c for c in got["refresh"] if c < first]) >= 2  # the idle time's, on time
    sched = schedule(t, requests, [c - first for c in got["admit"]])
    assert [c - first for c in got["read"]] == sched.read.tolist()
    assert [c - first for c in got["activate"]] == [int(c) for c in sched.activate if c >= 0]
    framed = [c - first for c in got["refresh"] if first <= c < got["read"][-1]]
    assert framed == sched.refresh[:, 1].tolist() and len(framed) >= 3
