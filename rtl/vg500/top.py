"""The VolumePro 500 (vg500) top: four Cube-4-lineage pipelines fed from four SDR SDRAM
modules through the two-level skewed mini-block memory, its controllers and the slab
buffer.

# Ref: architectures.md section 3 (VolumePro 500: Cube-4's pipelines, shear-warp order,
#      mini-blocks in SDRAM skewed across modules then banks, US 6,266,733) and 9.1
#      (voxel memory controller, de-skew); rtl/top.py (the pipelines reused here).

Structure:

* **pipelines** (:class:`rtl.top.Cube4Top`, unchanged): the slice read, slice buffers,
  ring, interpolation, gradients from samples, classification, shading, compositing,
  compositing buffer and pixel bus.  Its voxel memory port is served by the slab buffer.
* **SDRAM front end** (:class:`rtl.vg500.front_end.SdramFrontEnd`): the mini-block order
  of the slabs, one :class:`~rtl.vg500.sdram_ctrl.SdramController` per module driving
  that module's pins, the de-skew of the returned bursts.
* **slab buffer**: on chip, four banks (bank ``(x + y + z) mod 4``, the pipeline that
  reads the voxel), each written by any of the four modules' de-skewed words and read by
  its pipeline; ``slab_entries`` words each, a ring: mini-block beam ``g`` (processing
  order) holds ``4 C`` words of a bank from ``4 C g`` on, word ``(s 2 + r) C + b div 4``
  for its slice ``s`` and row ``r`` of the pair and beam position ``b``, all modulo
  ``slab_entries``.  The front end's credit keeps at most ``slab_entries div 4 C`` beams
  in it, so the live ones never share a word; the storage does not grow with the volume.
  The read address follows the pipelines' slot (slice, row, slot ``g`` along the beam,
  counted here as the pipelines step).
* **hold**: the pipelines' slot reads voxel slice ``q``, row ``a``; when the mini-block
  beam holding it (slab ``q div 2``, rows ``a div 2``) has not fully arrived, the whole
  pipeline top is held for the clock (one clock enable): memory stalls emerge from the
  SDRAM's own timing.  A mini-block beam is freed when its last row of its slab's later
  slice (processing order) has been read.

The host writes what the Cube-4 top's host writes (geometry, view, tables; the VLI
driver's part) and loads the volume into the SDRAM devices outside the chip; no latency,
period or stall count.  ``cycles`` are the pipeline top's own plus the held clocks.
"""

from __future__ import annotations

from amaranth import Cat, EnableInserter, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from models.datapath import Datapath
from rtl.top import Cube4Top
from rtl.top_layouts import TopGeometry
from rtl.vg500.front_end import MBB_BITS, MODULES, SdramFrontEnd
from rtl.vg500.sdram_ctrl import SdramTiming

__all__ = ["Vg500Top", "PINS_OUT", "PINS_IN"]

#: Each module's pins (sdram_pins.md), prefixed ``sdram<m>_`` on the top.
PINS_OUT = ("cke", "cs_n", "ras_n", "cas_n", "we_n", "ba", "a", "dqm", "dq_out", "dq_oe")
PINS_IN = ("dq_in",)
#: The pipeline top's ports the vg500 top does not pass through (its memory port).
_INNER = ("vmem_addr", "vmem_en", "vmem_data", "cycles", "read_slice", "read_row")
_INNER += ("read_valid", "read_last")


class Vg500Top(wiring.Component):
    """The vg500: pipelines, SDRAM front end, slab buffer (module docstring).

    Parameters
    ----------
    dp : Datapath
    geo : TopGeometry
        Pipelines (4) and the largest volume.
    timing : SdramTiming
        The devices' timing in clocks (the arch file's ``[memory]``).
    slab_entries : int
        The slab buffer's capacity in voxels per pipeline (``[buffers]``).
    """

    def __init__(self, dp: Datapath, geo: TopGeometry, timing: SdramTiming, slab_entries: int):
        if geo.pipelines != MODULES:
            raise ValueError(f"the vg500 has {MODULES} pipelines")
        self.dp, self.geo, self.timing = dp, geo, timing
        self.slab_entries = int(slab_entries)
        self.core = Cube4Top(dp, geo)
        self.fe = SdramFrontEnd(timing)
        members = {
            name: member
            for name, member in self.core.signature.members.items()
            if name not in _INNER
        }
        for k in range(MODULES):
            for pin in PINS_OUT:
                members[f"sdram{k}_{pin}"] = Out(len(getattr(self.fe.ctrls[k], pin)))
            members[f"sdram{k}_dq_in"] = In(16)
        members |= {
            "cycles": Out(32),
            "hold_cycles": Out(32),
            "bursts": Out(32),
            "memory_ready": Out(1),
        }
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        core, fe, geo = self.core, self.fe, self.geo
        hold = Signal(name="memory_hold")
        m.submodules.pipelines = EnableInserter(~hold)(core)
        m.submodules.front_end = fe
        self._pass_through(m, hold)
        for k, ctl in enumerate(fe.ctrls):
            for pin in PINS_OUT:
                m.d.comb += getattr(self, f"sdram{k}_{pin}").eq(getattr(ctl, pin))
            m.d.comb += ctl.dq_in.eq(getattr(self, f"sdram{k}_dq_in"))
        # Frame geometry for the front end, from the pipelines' registers.
        nz = Mux(self.kp == 0, self.n_kp, self.n_a)
        side = Signal(geo.axis_bits + 1)
        biggest = Mux(self.nx > self.ny, self.nx, self.ny)
        m.d.comb += side.eq(Mux(nz > biggest, nz, biggest))
        n_slabs = Signal(geo.axis_bits + 1)
        n_u = Signal(geo.axis_bits + 1)
        m.d.comb += [
            n_slabs.eq((self.n_kp + 1) >> 1),
            n_u.eq((self.n_a + 1) >> 1),
            fe.start.eq(self.start),
            fe.kp.eq(self.kp),
            fe.forward.eq(self.forward),
            fe.n_slabs.eq(n_slabs),
            fe.n_u.eq(n_u),
            fe.n_mb.eq((self.n_b + 1) >> 1),
            fe.nb.eq((side + 1) >> 1),
            fe.c.eq(self.c),
            fe.slab_entries.eq(self.slab_entries),
            self.memory_ready.eq(fe.ready),
            self.bursts.eq(fe.bursts),
        ]
        # The hold: the slot's mini-block beam has not arrived.
        q, a = core.read_slice, core.read_row
        slab = q >> 1
        proc = Mux(self.forward, slab, n_slabs - 1 - slab)
        g_read = Signal(MBB_BITS + geo.axis_bits)
        m.d.comb += g_read.eq(proc * n_u + (a >> 1))
        m.d.comb += hold.eq(core.read_valid & (g_read >= fe.delivered))
        # Freeing: the last read of a mini-block beam (its later slice, its later row).
        last_slice = Mux(self.forward, q[0] | (q == self.n_kp - 1), ~q[0])
        last_row = a[0] | (a == self.n_a - 1)
        freed = Signal(MBB_BITS)
        with m.If(self.start):
            m.d.sync += freed.eq(0)
        with m.Elif(
            core.read_valid & core.read_last & ~hold & ~core.frozen & last_slice & last_row
        ):
            m.d.sync += freed.eq(freed + 1)
        m.d.comb += fe.freed.eq(freed)
        held = Signal(32)
        with m.If(self.start):
            m.d.sync += held.eq(0)
        with m.Elif(hold):
            m.d.sync += held.eq(held + 1)
        m.d.comb += [self.hold_cycles.eq(held), self.cycles.eq(core.cycles + held)]
        self._slab_buffer(m, hold, nz, n_slabs, n_u, g_read)
        return m

    def _pass_through(self, m, hold):
        for name in self.signature.members:
            if name.startswith("sdram") or name in ("cycles", "hold_cycles", "bursts"):
                continue
            if name == "memory_ready":
                continue
            ours, theirs = getattr(self, name), getattr(self.core, name)
            if name == "load":
                m.d.comb += [theirs.valid.eq(ours.valid), theirs.payload.eq(ours.payload)]
            elif name == "pixel":
                # A held top pops nothing: its pixel is offered again when it runs.
                m.d.comb += [
                    ours.valid.eq(theirs.valid & ~hold),
                    ours.payload.eq(theirs.payload),
                    theirs.ready.eq(ours.ready),
                ]
            elif self.signature.members[name].flow == In:
                m.d.comb += theirs.eq(ours)
            else:
                m.d.comb += ours.eq(theirs)

    def _ring_word(self, m, g, q, a, w, name):
        """The slab buffer word of slot ``w`` of slice ``q``, row ``a`` of mini-block beam
        ``g``: ``(4 g + 2 (q mod 2) + a mod 2) C + w`` modulo ``slab_entries``."""
        word = Signal(range(self.slab_entries), name=name)
        linear = ((g << 2) + (q[0] << 1) + a[0]) * self.c + w
        m.d.comb += word.eq(linear % self.slab_entries)
        return word

    def _slab_buffer(self, m, hold, nz, n_slabs, n_u, g_read):
        """Four ring banks (module docstring); each module's de-skewed word goes to the
        bank of its voxel, at its mini-block beam's place in the ring."""
        core, fe, dp = self.core, self.fe, self.dp
        B, P, kp = dp.voxel_bits, self.geo.pipelines, self.kp
        writes = []
        for j in range(MODULES):
            x, y, z = (getattr(fe, f"wr_{c}{j}") for c in "xyz")
            inside = (x < self.nx) & (y < self.ny) & (z < nz)
            # (slice, row, beam) of the voxel by the principal axis (the pipelines' read).
            q = Mux(kp == 0, z, Mux(kp == 1, y, x))
            a = Mux(kp == 0, y, z)
            b = Mux(kp == 2, y, x)
            proc = Mux(self.forward, q >> 1, n_slabs - 1 - (q >> 1))
            g = Signal(MBB_BITS, name=f"deskew_mbb{j}")
            m.d.comb += g.eq(proc * n_u + (a >> 1))
            bank = Signal(2, name=f"deskew_bank{j}")
            m.d.comb += bank.eq((x + y + z)[:2])
            addr = self._ring_word(m, g, q, a, b >> 2, f"deskew_addr{j}")
            writes.append(
                (getattr(fe, f"wr_en{j}") & inside, bank, addr, getattr(fe, f"wr_data{j}"))
            )
        # The pipelines' slot along the beam: one step per clock they read and run.
        slot = Signal(self.geo.axis_bits, name="read_slot")
        step = core.read_valid & ~hold & ~core.frozen
        with m.If(self.start):
            m.d.sync += slot.eq(0)
        with m.Elif(step):
            m.d.sync += slot.eq(Mux(core.read_last, 0, slot + 1))
        q, a = core.read_slice, core.read_row
        read_addr = self._ring_word(m, g_read, q, a, slot, "slab_read_addr")
        data_bits = []
        for k in range(P):
            mem = Memory(shape=unsigned(B), depth=self.slab_entries, init=[])
            m.submodules[f"slab_buffer{k}"] = mem
            for en, bank, addr, word in writes:
                wp = mem.write_port()
                m.d.comb += [wp.addr.eq(addr), wp.data.eq(word[:B]), wp.en.eq(en & (bank == k))]
            rp = mem.read_port()
            m.d.comb += [rp.addr.eq(read_addr), rp.en.eq(core.vmem_en & ~hold)]
            data_bits.append(rp.data)
        m.d.comb += core.vmem_data.eq(Cat(*data_bits))
