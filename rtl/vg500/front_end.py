"""The vg500's volume memory front end: the mini-block order of the slabs, four SDRAM
controllers and the de-skew of their bursts into the on-chip slab buffer.

# Ref: architectures.md section 3 (US 6,266,733: 2x2x2 mini-blocks skewed across modules
#      ``s mod M`` and then across banks ``(s div M) mod K``, ``s = bx + by + bz``; one
#      mini-block one burst of 8; a de-skewing network) and 9.1 (voxel memory controller).

Order (:class:`MiniBlockOrder`, one per module, all counters): slab after slab in the
processing order (``forward``: increasing slab index), mini-block beam (mbb: two rows
``2u, 2u + 1`` of axis ``a``) after mbb, mini-block after mini-block along axis ``b``;
module ``m`` takes the mini-blocks with ``s mod 4 = m``, i.e. every fourth along the beam
from ``(m - slab - u) mod 4``.  Its word address is the two-level skew's:
``lb = (bz nb + by) pitch + bx`` with ``pitch = ceil(nb / 4K) 4K``, word ``(lb div 4K) 8``,
row and column of the device page.  A second copy of the same counters walks the bursts
as their data return (the words come back in request order), so each word's voxel is
known without a tag queue: word ``j`` of a burst is voxel ``(2 bx + j[0], 2 by + j[1],
2 bz + j[2])``.

Credit: module ``m`` requests the first burst of mbb ``g`` only when fewer than the slab
buffer's capacity are outstanding, ``(g - freed + 1) 4 C <= slab_entries`` (the buffer
holds ``4 C`` words per pipeline per mbb; ``freed`` counts the mbbs the pipelines have
read for the last time).  ``delivered`` is the number of mbbs whose every burst on every
module has returned.
"""

from __future__ import annotations

from amaranth import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from rtl.vg500.sdram_ctrl import SdramController, SdramTiming

__all__ = ["MiniBlockOrder", "SdramFrontEnd", "MODULES", "AXIS_BITS"]

#: SDRAM modules (one per pipeline).
MODULES = 4
#: Bits of a voxel coordinate (volumes up to 256 per axis, the vg500's limit).
AXIS_BITS = 9
#: Bits of an mbb index.
MBB_BITS = 16


class MiniBlockOrder:
    """Counters over module ``m``'s mini-blocks in the slab order (see the module
    docstring); ``advance`` steps to the next, ``valid`` until the frame's last."""

    def __init__(self, m: Module, module: int, regs: dict, name: str):
        self.module = module
        ab = AXIS_BITS
        self.slab_i = Signal(ab, name=f"{name}_slab_i")  # processing index
        self.u = Signal(ab, name=f"{name}_u")
        self.mb = Signal(ab + 2, name=f"{name}_mb")
        self.g = Signal(MBB_BITS, name=f"{name}_g")  # mbb index
        self.valid = Signal(name=f"{name}_valid")
        self.advance = Signal(name=f"{name}_advance")
        self.restart = Signal(name=f"{name}_restart")
        r = regs
        slab = Signal(ab, name=f"{name}_slab")
        m.d.comb += slab.eq(Mux(r["forward"], self.slab_i, r["n_slabs"] - 1 - self.slab_i))
        self.slab = slab
        self.last_mb = Signal(name=f"{name}_last_mb")
        m.d.comb += self.last_mb.eq(self.mb + 4 >= r["n_mb"])

        def first(slab_abs, u):
            return (module + 3 * 4 * 256 - slab_abs - u)[:2]

        next_u = Signal(ab + 1, name=f"{name}_next_u")
        next_i = Signal(ab + 1, name=f"{name}_next_i")
        m.d.comb += [next_u.eq(self.u + 1), next_i.eq(self.slab_i + 1)]
        next_slab = Mux(r["forward"], next_i, r["n_slabs"] - 2 - self.slab_i)
        with m.If(self.restart):
            start_slab = Mux(r["forward"], 0, r["n_slabs"] - 1)
            m.d.sync += [
                self.slab_i.eq(0),
                self.u.eq(0),
                self.g.eq(0),
                self.mb.eq(first(start_slab, 0)),
                self.valid.eq(1),
            ]
        with m.Elif(self.advance):
            with m.If(~self.last_mb):
                m.d.sync += self.mb.eq(self.mb + 4)
            with m.Elif(next_u < r["n_u"]):
                m.d.sync += [
                    self.u.eq(next_u),
                    self.mb.eq(first(slab, next_u)),
                    self.g.eq(self.g + 1),
                ]
            with m.Elif(next_i < r["n_slabs"]):
                m.d.sync += [
                    self.slab_i.eq(next_i),
                    self.u.eq(0),
                    self.mb.eq(first(next_slab, 0)),
                    self.g.eq(self.g + 1),
                ]
            with m.Else():
                m.d.sync += self.valid.eq(0)

    def blocks(self, regs: dict) -> tuple:
        """Mini-block coordinates ``(bx, by, bz)`` by the principal axis."""
        kp, slab, u, mb = regs["kp"], self.slab, self.u, self.mb
        bz = Mux(kp == 0, slab, u)
        by = Mux(kp == 0, u, Mux(kp == 1, slab, mb))
        bx = Mux(kp == 2, slab, mb)
        return bx, by, bz


class SdramFrontEnd(wiring.Component):
    """Four controllers, their mini-block orders and the de-skew (module docstring).

    Ports: the frame registers (``kp``, ``forward``, ``n_slabs``, ``n_u``, ``n_mb``,
    ``nb``, ``c``, ``slab_entries``), ``start``, ``freed`` (mbbs released by the
    pipelines); out ``delivered``, per module a write of one voxel (``wr_en``,
    ``wr_x/y/z``, ``wr_data``), ``ready`` (power-up done) and each module's pins.
    """

    def __init__(self, t: SdramTiming, *, init_wait: int = 8):
        self.t, self.init_wait = t, init_wait
        ab = AXIS_BITS
        ports = {
            "start": In(1),
            "kp": In(2),
            "forward": In(1),
            "n_slabs": In(ab),
            "n_u": In(ab),
            "n_mb": In(ab),
            "nb": In(ab),
            "c": In(ab),
            "slab_entries": In(32),
            "freed": In(MBB_BITS),
            "delivered": Out(MBB_BITS),
            "ready": Out(1),
            "bursts": Out(32),
        }
        for k in range(MODULES):
            ports |= {
                f"wr_en{k}": Out(1),
                f"wr_x{k}": Out(ab),
                f"wr_y{k}": Out(ab),
                f"wr_z{k}": Out(ab),
                f"wr_data{k}": Out(t.word_bits),
            }
        super().__init__(ports)
        self.ctrls = [SdramController(t, init_wait=init_wait) for _ in range(MODULES)]

    def elaborate(self, platform):
        m = Module()
        t = self.t
        regs = {
            "kp": self.kp,
            "forward": self.forward,
            "n_slabs": self.n_slabs,
            "n_u": self.n_u,
            "n_mb": self.n_mb,
        }
        mk = MODULES * t.banks  # mini-blocks per skew period (modules x banks)
        pitch = Signal(AXIS_BITS + 4)
        m.d.comb += pitch.eq(((self.nb + mk - 1) // mk) * mk)
        mbb_words = Signal(32)
        m.d.comb += mbb_words.eq(4 * self.c)
        done_g = []
        for k, ctl in enumerate(self.ctrls):
            m.submodules[f"ctl{k}"] = ctl
            issue = MiniBlockOrder(m, k, regs, f"issue{k}")
            back = MiniBlockOrder(m, k, regs, f"back{k}")
            m.d.comb += [issue.restart.eq(self.start), back.restart.eq(self.start)]
            m.d.comb += ctl.restart.eq(self.start)
            bx, by, bz = issue.blocks(regs)
            lb = Signal(32, name=f"lb{k}")
            m.d.comb += lb.eq((bz * self.nb + by) * pitch + bx)
            word = Signal(32, name=f"word{k}")
            m.d.comb += word.eq((lb // mk) << 3)
            # The credit: first burst of mbb g only while the buffer has room for it.
            room = Signal(name=f"room{k}")
            m.d.comb += room.eq((issue.g - self.freed + 1) * mbb_words <= self.slab_entries)
            m.d.comb += [
                ctl.req.valid.eq(issue.valid & room & ~self.start),
                ctl.req.payload.bank.eq(((bx + by + bz) >> 2) % t.banks),
                ctl.req.payload.row.eq(word // t.columns),
                ctl.req.payload.col.eq(word % t.columns),
                issue.advance.eq(ctl.req.valid & ctl.req.ready),
            ]
            # Data return: word j of the burst at the back counter's mini-block.
            beat = Signal(3, name=f"beat{k}")
            with m.If(self.start):
                m.d.sync += beat.eq(0)
            with m.Elif(ctl.rdata_valid):
                m.d.sync += beat.eq(beat + 1)
            rx, ry, rz = back.blocks(regs)
            m.d.comb += [
                getattr(self, f"wr_en{k}").eq(ctl.rdata_valid),
                getattr(self, f"wr_x{k}").eq(_coord(beat[0], rx)),
                getattr(self, f"wr_y{k}").eq(_coord(beat[1], ry)),
                getattr(self, f"wr_z{k}").eq(_coord(beat[2], rz)),
                getattr(self, f"wr_data{k}").eq(ctl.rdata_word),
                back.advance.eq(ctl.rdata_valid & ctl.rdata_last),
            ]
            # mbbs this module has returned whole.
            got = Signal(MBB_BITS, name=f"returned{k}")
            with m.If(self.start):
                m.d.sync += got.eq(0)
            with m.Elif(ctl.rdata_valid & ctl.rdata_last & back.last_mb):
                m.d.sync += got.eq(got + 1)
            done_g.append(got)
        least = done_g[0]
        for k in range(1, MODULES):
            least = Mux(done_g[k] < least, done_g[k], least)
        m.d.comb += self.delivered.eq(least)
        m.d.comb += self.ready.eq(sum(c.ready for c in self.ctrls) == MODULES)
        bursts = Signal(32)
        with m.If(self.start):
            m.d.sync += bursts.eq(0)
        with m.Else():
            m.d.sync += bursts.eq(bursts + sum(c.cmd_read for c in self.ctrls))
        m.d.comb += self.bursts.eq(bursts)
        return m


def _coord(low, high):
    """``2 high + low``: a voxel coordinate from its mini-block and offset bit."""
    return (high << 1) | low
