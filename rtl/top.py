"""The Cube-4 pipeline top: skewed volume memory, slice buffers, neighbour links, the
interpolator / classifier / compositor chain of every pipeline, the compositing buffer
and the pixel bus, rendering a small volume end to end with the cycle rung's timing.

# Ref: architectures.md sections 1.1-1.4 (Pfister & Kaufman, VolVis 1996: slice-parallel
#      ray casting on a skewed memory, local neighbour links, pixel bus) and 9.1-9.3
#      (units, buffer sizes, latencies); docs/cycle.md (the timing rules reproduced).

Structure (``P`` pipelines, volumes up to ``N`` voxels per axis):

* **memory modules**: module ``m`` holds the voxels ``(x, y, z)`` with
  ``(x + y + z) mod P = m`` at word ``(z ny + y) ceil(nx / P) + x div P`` (the cycle
  rung's layout); the host writes them through the wide ``load`` port (P voxels a word).
* **slice read**: in period ``p`` every pipeline reads one voxel of slice ``p`` per clock,
  in beam order: slot ``t = a C + g`` (``C = ceil(n_b / P)``) is voxel
  ``(a, b = P g + ((m - q - a) mod P))`` of slice ``q``, written to its slice buffer at
  ``t``.  Slice buffers hold three slices (one filling, one read, one guard), so the
  first slice is read one period ahead of its samples (the cycle rung's priming slice).
* **sample slots**: in period ``p`` pipeline ``m`` evaluates, in the same slot order, the
  sample of slice ``p - 1`` whose nearest voxel is its slot's voxel (the cycle rung's
  lane rule): the cell ``(a - da, b - db)`` (``d = 1`` where the slice's fraction is
  ``>= 1/2``), corners clamped to the volume (the boundary multiplexers).  The corners
  live in modules ``m - 2 .. m + 2``: each pipeline reads them from its own and its two
  neighbours' slice buffers on either side (local links; no global bus).
* **per-slice constants** (the host's geometry unit, parallel projection): slice index,
  cell shift ``(da, db)``, base-plane offset ``(ia, ib)`` and the quantised weights
  ``(wa, wb)`` of every step, in a table the host writes before the frame.  The ray
  table holds each base-plane ray's first and last step.
* **units**: ``Interp`` (bilinear on the slice plane: principal weight 0) ->
  ``Classify`` -> ``Composite``, II = 1, no backpressure inside a frame.  The
  compositing buffer (one entry per base-plane ray: RGBA, MIP, alive) is read one clock
  before the compositor and written when it answers.
* **pixel bus**: a ray whose last sample left the compositor joins the pixel FIFO; the
  rays of slice period ``p`` are committed ``latency`` clocks after the period ends (the
  machine's pipeline latency, rule 5 of docs/cycle.md) and drained one per clock
  through the ``pixel`` stream (ray number, accumulators), which may be back-pressured.

Timing: the prime period takes ``T = n_a C`` clocks, every other ``T +
slice_overhead``; ``cycles`` counts from the first clock of the prime period to the
last pixel popped from the pixel FIFO, which is rule 1-6 of the cycle rung for parallel
views (no stretch; pixel-FIFO stalls are not modelled: the FIFO holds every ray).
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth import Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from models.datapath import Datapath
from rtl.classify import Classify
from rtl.common import bit_length, divide_by_constant
from rtl.composite import Composite
from rtl.interp import Interp
from rtl.top_layouts import (
    LOAD_CORRECTION,
    LOAD_LUT,
    LOAD_RAYS,
    LOAD_SLICES,
    LOAD_VOLUME,
    TopGeometry,
    buffer_layout,
    load_layout,
    pixel_layout,
    ray_layout,
    slice_layout,
)

__all__ = [
    "Cube4Top",
    "TopConfig",
    "TopGeometry",
    "LOAD_VOLUME",
    "LOAD_LUT",
    "LOAD_CORRECTION",
    "LOAD_RAYS",
    "LOAD_SLICES",
    "slice_layout",
    "ray_layout",
    "pixel_layout",
    "load_layout",
    "ISSUE_TO_WRITEBACK",
    "RMW_WINDOW",
]

EVAL_DELAY = 3  # clocks between a slot's memory read and its sample's address stage
# Slot issue -> compositor answer: eval delay 3, address 1, buffer read 1, interp 4,
# classify 2, composite 3.
ISSUE_TO_WRITEBACK = EVAL_DELAY + 2 + 4 + 2 + 3
#: Clocks between a ray's compositing-buffer read and its write becoming visible.
RMW_WINDOW = 5
WHEEL = 64  # commit delay line: latency - 16 < 64 clocks
#: A sample slot's issue to its compositor answer (the top's own datapath depth).
LATENCY = ISSUE_TO_WRITEBACK
II = 1


@dataclass(frozen=True, kw_only=True)
class TopConfig:
    """``hwsim rtl build top`` parameters: pipelines, largest volume, voxel width (the
    unit formats are the defaults; a frame's own datapath comes from its machine)."""

    pipelines: int = 4
    max_axis: int = 16
    voxel_bits: int = 12

    def __post_init__(self):
        for name, lo, hi in (("pipelines", 1, 16), ("max_axis", 4, 64), ("voxel_bits", 1, 16)):
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise ValueError(f"{name} {lo}..{hi}")

    def build(self) -> Cube4Top:
        return Cube4Top(
            Datapath(voxel_bits=self.voxel_bits), TopGeometry(self.pipelines, self.max_axis)
        )


def _mod(value, modulus: int, bound: int):
    """``value mod modulus`` of an unsigned ``value < bound`` by repeated subtraction."""
    out = value
    for k in reversed(range(1, -(-bound // modulus))):
        out = Mux(out >= k * modulus, out - k * modulus, out)
    return out


class Cube4Top(wiring.Component):
    """``P`` Cube-4 pipelines with memory, slice buffers, compositing buffer and pixel bus.

    Parameters
    ----------
    dp : Datapath
        Voxel width and unit formats (interp, classify, composite).
    geo : TopGeometry
        Pipelines and the largest volume the memories hold.

    Ports
    -----
    load : In stream, always ready
        Host writes (:func:`load_layout`) before a frame.
    start : In(1)
        Pulse: render one frame with the registers below.
    n_kp, n_a, n_b, nx, ny, cx, kp, steps, c, t, overhead, latency, width, height, mip,
    ert_enable, ert_threshold : In
        Frame registers: slice and in-slice sizes, the volume's ``nx``, ``ny`` and
        ``ceil(nx / P)``, the principal axis (0 z, 1 y, 2 x), steps, ``C``, ``T``, slice
        overhead and pipeline latency (clocks), base-plane width and height, MIP mode,
        early termination.
    pixel : Out stream
        :func:`pixel_layout` (back-pressure allowed).
    busy, done : Out(1)
        A frame is running / has finished (``done`` holds until the next ``start``).
    cycles, samples : Out(32)
        The frame's clocks (first prime clock to last pixel popped) and samples composited.
    """

    def __init__(self, dp: Datapath, geo: TopGeometry):
        self.dp, self.geo = dp, geo
        ab = geo.axis_bits
        super().__init__(
            {
                "load": In(stream.Signature(load_layout(geo, dp), always_ready=True)),
                "start": In(1),
                "n_kp": In(ab),
                "n_a": In(ab),
                "n_b": In(ab),
                "nx": In(ab),
                "ny": In(ab),
                "cx": In(ab),
                "kp": In(2),
                "c": In(ab),
                "t": In(bit_length(geo.t_max)),
                "overhead": In(16),
                "latency": In(8),
                "width": In(bit_length(2 * geo.max_axis)),
                "height": In(bit_length(2 * geo.max_axis)),
                "mip": In(1),
                "ert_enable": In(1),
                "ert_threshold": In(dp.composite.acc_frac_bits + 1),
                "pixel": Out(stream.Signature(pixel_layout(geo, dp))),
                "busy": Out(1),
                "done": Out(1),
                "cycles": Out(32),
                "samples": Out(32),
            }
        )

    # ------------------------------------------------------------------ sequencer

    def _sequencer(self, m: Module, slices):
        """Periods ``p = 0 .. n_kp`` of ``T`` (+ overhead) clocks; slot counters."""
        geo = self.geo
        ab = geo.axis_bits
        P = geo.pipelines
        s = {
            "run": Signal(name="run"),
            "period": Signal(ab + 1, name="period"),
            "tick": Signal(16, name="tick"),
            "a": Signal(ab, name="slot_a"),
            "g": Signal(ab, name="slot_g"),
            "amod": Signal(bit_length(P), name="slot_amod"),
            "bank": Signal(2, name="bank"),
            "cycle": Signal(32, name="cycle"),
        }
        lay = slice_layout(geo, self.dp)
        mem_c = Signal(lay, name="mem_consts")  # slice read in this period (p)
        eval_c = Signal(lay, name="eval_consts")  # slice evaluated (p - 1)
        prefetch = slices.read_port()
        m.d.comb += [prefetch.addr.eq(s["period"] + 1), prefetch.en.eq(1)]
        setup = Signal(2, name="setup")
        period_len = Signal(17, name="period_len")
        m.d.comb += period_len.eq(Mux(s["period"] == 0, self.t, self.t + self.overhead))
        slot_live = Signal(name="slot_live")
        m.d.comb += slot_live.eq(s["run"] & (s["tick"] < self.t))
        end = Signal(name="period_end")
        m.d.comb += end.eq(s["run"] & (s["tick"] == period_len - 1))
        with m.If(self.start):
            m.d.sync += [setup.eq(1), s["period"].eq(0)]
        with m.If(setup == 1):
            m.d.sync += setup.eq(2)  # prefetch address 1 settles; entry 0 read below
        # The first slice's entry comes through its own port (the prefetch port reads p + 1).
        first = slices.read_port()
        m.d.comb += [first.addr.eq(0), first.en.eq(1)]
        with m.If(setup == 2):
            m.d.sync += [
                setup.eq(0),
                s["run"].eq(1),
                s["tick"].eq(0),
                s["a"].eq(0),
                s["g"].eq(0),
                s["amod"].eq(0),
                s["bank"].eq(0),
                s["cycle"].eq(0),
                mem_c.eq(first.data),
            ]
        with m.If(s["run"]):
            m.d.sync += s["cycle"].eq(s["cycle"] + 1)
            m.d.sync += s["tick"].eq(s["tick"] + 1)
            with m.If(slot_live):
                with m.If(s["g"] == self.c - 1):
                    m.d.sync += [
                        s["g"].eq(0),
                        s["a"].eq(s["a"] + 1),
                        s["amod"].eq(Mux(s["amod"] == P - 1, 0, s["amod"] + 1)),
                    ]
                with m.Else():
                    m.d.sync += s["g"].eq(s["g"] + 1)
            with m.If(end):
                m.d.sync += [
                    s["tick"].eq(0),
                    s["a"].eq(0),
                    s["g"].eq(0),
                    s["amod"].eq(0),
                    s["period"].eq(s["period"] + 1),
                    s["bank"].eq(Mux(s["bank"] == 2, 0, s["bank"] + 1)),
                    eval_c.eq(mem_c),
                    mem_c.eq(prefetch.data),
                ]
                with m.If(s["period"] == self.n_kp):
                    m.d.sync += s["run"].eq(0)
        s["mem_valid"] = Signal(name="mem_valid")
        s["eval_valid"] = Signal(name="eval_valid")
        m.d.comb += [
            s["mem_valid"].eq(slot_live & (s["period"] < self.n_kp)),
            s["eval_valid"].eq(slot_live & (s["period"] >= 1)),
        ]
        s["end"] = end
        s["go"] = setup == 2
        s["mem_c"], s["eval_c"] = mem_c, eval_c
        return s

    # ------------------------------------------------------------------ elaborate

    def elaborate(self, platform):
        m = Module()
        dp, geo = self.dp, self.geo
        P, ab = geo.pipelines, geo.axis_bits
        B = dp.voxel_bits
        S = dp.interp.sample_frac_bits
        sample_bits = B + S
        load = self.load.payload

        def loading(target):
            return self.load.valid & (load.target == target)

        # Tables the host writes.
        m.submodules.slices = slices = Memory(
            shape=slice_layout(geo, dp), depth=geo.max_axis + 2, init=[]
        )
        wr = slices.write_port()
        m.d.comb += [wr.addr.eq(load.addr), wr.data.eq(load.data), wr.en.eq(loading(LOAD_SLICES))]
        m.submodules.rays = rays = Memory(shape=ray_layout(geo), depth=geo.max_rays, init=[])
        wr = rays.write_port()
        m.d.comb += [wr.addr.eq(load.addr), wr.data.eq(load.data), wr.en.eq(loading(LOAD_RAYS))]

        seq = self._sequencer(m, slices)
        m.d.comb += self.busy.eq(seq["run"])

        # ---------------------------------------------------------- memory -> slice buffers
        slice_bufs = []
        mem_c = seq["mem_c"]
        for k in range(P):
            module = Memory(shape=unsigned(B), depth=geo.module_words, init=[])
            m.submodules[f"module_{k}"] = module
            wr = module.write_port()
            m.d.comb += [
                wr.addr.eq(load.addr),
                wr.data.eq(load.data[k * B : (k + 1) * B]),
                wr.en.eq(loading(LOAD_VOLUME)),
            ]
            # Slot voxel of this pipeline: b = P g + ((k - q - a) mod P).
            r = Signal(bit_length(P), name=f"read_r{k}")
            m.d.comb += r.eq(_mod(k + 2 * P - mem_c.qm - seq["amod"], P, 3 * P))
            a, b = seq["a"], Signal(ab + 1, name=f"read_b{k}")
            m.d.comb += b.eq(seq["g"] * P + r)
            q = mem_c.q
            z = Mux(self.kp == 0, q, a)
            y = Mux(self.kp == 0, a, Mux(self.kp == 1, q, b))
            x = Mux(self.kp == 2, q, b)
            rd = module.read_port()
            addr = (z * self.ny + y) * self.cx + divide_by_constant(x, P, ab + 1)
            m.d.comb += [rd.addr.eq(addr), rd.en.eq(1)]
            read_valid = Signal(name=f"read_valid{k}")
            m.d.comb += read_valid.eq(seq["mem_valid"] & (b < self.n_b))
            # One clock later the voxel arrives; it is written at its slot.
            wslot = Signal(range(3 * geo.t_max), name=f"write_slot{k}")
            wvalid = Signal(name=f"write_valid{k}")
            m.d.sync += [
                wslot.eq(seq["bank"] * geo.t_max + seq["a"] * self.c + seq["g"]),
                wvalid.eq(read_valid),
            ]
            buf = Memory(shape=unsigned(B), depth=3 * geo.t_max, init=[])
            m.submodules[f"slice_buffer_{k}"] = buf
            wr = buf.write_port()
            m.d.comb += [wr.addr.eq(wslot), wr.data.eq(rd.data), wr.en.eq(wvalid)]
            slice_bufs.append(buf)

        # ---------------------------------------------------------- sample slots
        # The sequencer's slot, EVAL_DELAY clocks later (the slice written above is then
        # complete in its bank for the period after).
        slot = Cat(seq["a"], seq["g"], seq["amod"], seq["eval_valid"], seq["bank"])
        eval_c = seq["eval_c"]
        slot_d, const_d, period_d = slot, eval_c.as_value(), seq["period"]
        for k in range(EVAL_DELAY):
            nxt = Signal(len(slot), name=f"slot_d{k}")
            nc = Signal(len(eval_c.as_value()), name=f"consts_d{k}")
            np_ = Signal(ab + 1, name=f"period_d{k}")
            m.d.sync += [nxt.eq(slot_d), nc.eq(const_d), np_.eq(period_d)]
            slot_d, const_d, period_d = nxt, nc, np_
        ev_a = slot_d[:ab]
        ev_g = slot_d[ab : 2 * ab]
        ev_amod = slot_d[2 * ab : 2 * ab + bit_length(P)]
        ev_valid = slot_d[2 * ab + bit_length(P)]
        ev_bank = slot_d[2 * ab + bit_length(P) + 1 :]
        consts = data.View(slice_layout(geo, dp), const_d)
        # The evaluated slice's bank is the previous one.
        read_bank = Mux(ev_bank == 0, 2, ev_bank - 1)
        ev_j = period_d - 1

        buffer_lay = buffer_layout(dp)
        m.submodules.ray_buffer = ray_buffer = Memory(shape=buffer_lay, depth=geo.max_rays, init=[])
        clear = ray_buffer.write_port()
        m.d.comb += [
            clear.addr.eq(load.addr),
            clear.data.eq(Cat(Const(0, buffer_lay.size - 1), Const(1, 1))),
            clear.en.eq(loading(LOAD_RAYS)),
        ]
        ert_thr = self.ert_threshold
        finishing_out = []  # per pipeline: (valid & finishing, ray) at writeback
        sample_out = []
        for k in range(P):
            # Address stage (E0 -> E1 registers).
            r = _mod(k + 2 * P - consts.qm - ev_amod, P, 3 * P)
            b = Signal(ab + 1, name=f"ev_b{k}")
            m.d.comb += b.eq(ev_g * P + r)
            ca = Signal(signed(ab + 2), name=f"ca{k}")
            cb = Signal(signed(ab + 2), name=f"cb{k}")
            m.d.comb += [ca.eq(ev_a - consts.da), cb.eq(b - consts.db)]
            r0 = Mux(ca < 0, 0, ca)
            r1 = Mux(ca + 1 > self.n_a - 1, self.n_a - 1, ca + 1)
            c0 = Mux(cb < 0, 0, cb)
            c1 = Mux(cb + 1 > self.n_b - 1, self.n_b - 1, cb + 1)
            u = Signal(signed(geo.offset_bits + 2), name=f"u{k}")
            v = Signal(signed(geo.offset_bits + 2), name=f"v{k}")
            m.d.comb += [u.eq(ca - consts.ia), v.eq(cb - consts.ib)]
            inside = (
                ev_valid
                & (b < self.n_b)
                & (u >= 0)
                & (u < self.height)
                & (v >= 0)
                & (v < self.width)
            )
            corners = []
            for idx, (rr, cc) in enumerate(((r0, c0), (r0, c1), (r1, c0), (r1, c1))):
                addr = Signal(range(3 * geo.t_max), name=f"corner_addr{k}_{idx}")
                off = Signal(signed(4), name=f"corner_off{k}_{idx}")
                m.d.sync += [
                    addr.eq(
                        read_bank * geo.t_max
                        + rr[:ab] * self.c
                        + divide_by_constant(cc[:ab], P, ab)
                    ),
                    off.eq((rr - ev_a) + (cc - b)),
                ]
                corners.append((idx, addr, off))
            ray = Signal(geo.ray_bits, name=f"ray{k}")
            live = Signal(name=f"live{k}")
            j1 = Signal(ab + 1, name=f"j1_{k}")
            wts = Signal(2 * dp.interp.weight.width, name=f"weights1_{k}")
            m.d.sync += [
                ray.eq(u[: geo.ray_bits] * self.width + v[: geo.ray_bits]),
                live.eq(inside),
                j1.eq(ev_j),
                wts.eq(Cat(consts.wa, consts.wb)),
            ]
            # Buffer stage (E1 -> E2): slice buffers and ray table read.
            possible = {-2: (0,), -1: (0, 1, 2), 0: (0, 1, 2, 3), 1: (1, 2, 3), 2: (3,)}
            values = []
            offs2 = []
            for idx, addr, off in corners:
                ports = {}
                for o, users in possible.items():
                    if idx in users:
                        port = slice_bufs[(k + o) % P].read_port()
                        m.d.comb += [port.addr.eq(addr), port.en.eq(1)]
                        ports[o] = port
                off2 = Signal(signed(4), name=f"corner_off2_{k}_{idx}")
                m.d.sync += off2.eq(off)
                offs2.append(off2)
                value = Signal(B, name=f"corner{k}_{idx}")
                with m.Switch(off2):
                    for o, port in ports.items():
                        with m.Case(o):
                            m.d.comb += value.eq(port.data)
                values.append(value)
            ray_rd = rays.read_port()
            m.d.comb += [ray_rd.addr.eq(ray), ray_rd.en.eq(1)]
            ray2 = Signal(geo.ray_bits, name=f"ray2_{k}")
            live2 = Signal(name=f"live2_{k}")
            j2 = Signal(ab + 1, name=f"j2_{k}")
            wts2 = Signal(len(wts), name=f"weights2_{k}")
            m.d.sync += [ray2.eq(ray), live2.eq(live), j2.eq(j1), wts2.eq(wts)]
            span = data.View(ray_layout(geo), ray_rd.data)
            takes = live2 & (span.j_lo <= j2) & (j2 <= span.j_hi)
            last = j2 == span.j_hi

            interp = Interp(dp.interp, B)
            classify = Classify(dp.classify, B, S)
            composite = Composite(dp.composite, sample_bits)
            m.submodules[f"interp_{k}"] = interp
            m.submodules[f"classify_{k}"] = classify
            m.submodules[f"composite_{k}"] = composite
            w = dp.interp.weight.width
            ip = interp.i.payload
            m.d.comb += [
                interp.i.valid.eq(takes),
                ip.frac[0].eq(0),
                ip.frac[1].eq(wts2[:w]),
                ip.frac[2].eq(wts2[w:]),
            ]
            for c in range(8):
                m.d.comb += ip.voxels[c].eq(values[c % 4])
            # Classification LUT and opacity-correction table: broadcast loads.
            m.d.comb += [
                classify.load.valid.eq(loading(LOAD_LUT)),
                classify.load.payload.table.eq(0),
                classify.load.payload.addr.eq(load.addr),
                classify.load.payload.data.eq(load.data),
                classify.gm_scale.eq(0),
                classify.modulate.eq(0),
                composite.load.valid.eq(loading(LOAD_CORRECTION)),
                composite.load.payload.addr.eq(load.addr),
                composite.load.payload.data.eq(load.data),
                composite.ert_threshold.eq(ert_thr),
                composite.ert_enable.eq(self.ert_enable),
                interp.o.ready.eq(1),
                classify.o.ready.eq(1),
                composite.o.ready.eq(1),
            ]
            # interp -> classify; the sample travels beside the classifier (2 clocks).
            m.d.comb += [
                classify.i.valid.eq(interp.o.valid),
                classify.i.payload.sample.eq(interp.o.payload.sample),
                classify.i.payload.magnitude.eq(0),
            ]
            side = Cat(ray2, last)
            side_d = side
            for d in range(4 + 2 - 1):  # to E7: one clock before the compositor's input
                nxt = Signal(len(side), name=f"side{k}_{d}")
                m.d.sync += nxt.eq(side_d)
                side_d = nxt
            sample_d = interp.o.payload.sample
            for d in range(2):
                nxt = Signal(sample_bits, name=f"sample{k}_{d}")
                m.d.sync += nxt.eq(sample_d)
                sample_d = nxt
            ray7 = side_d[: geo.ray_bits]
            buf_rd = ray_buffer.read_port()
            m.d.comb += [buf_rd.addr.eq(ray7), buf_rd.en.eq(1)]
            side8 = Signal(len(side), name=f"side8_{k}")
            m.d.sync += side8.eq(side_d)
            entry = data.View(buffer_lay, buf_rd.data)
            cp = composite.i.payload
            m.d.comb += [
                composite.i.valid.eq(classify.o.valid),
                cp.acc.eq(entry.acc),
                cp.rgb.eq(classify.o.payload.rgb),
                cp.alpha.eq(classify.o.payload.alpha),
                cp.mip.eq(entry.mip),
                cp.sample.eq(sample_d),
            ]
            # Writeback (E11): the compositor's answer, for rays still alive.
            side_w = side8
            alive_w = entry.alive
            for d in range(3):
                nxt = Signal(len(side) + 1, name=f"sidew{k}_{d}")
                m.d.sync += nxt.eq(Cat(side_w[: len(side)], alive_w))
                side_w, alive_w = nxt, nxt[len(side)]
            ray_w = side_w[: geo.ray_bits]
            last_w = side_w[geo.ray_bits]
            wb = ray_buffer.write_port()
            out = composite.o.payload
            counted = composite.o.valid & (alive_w | self.mip)
            m.d.comb += [
                wb.addr.eq(ray_w),
                wb.data.eq(Cat(out.acc, out.mip, ~out.terminated)),
                wb.en.eq(counted),
            ]
            finishing_out.append((composite.o.valid & last_w, ray_w))
            sample_out.append(counted)

        # ---------------------------------------------------------- pixel bus
        depth = geo.max_rays
        pb = bit_length(depth)  # pointers carry one wrap bit
        m.submodules.pixel_fifo = fifo = Memory(shape=unsigned(geo.ray_bits), depth=depth, init=[])
        stage_ptr = Signal(pb, name="stage_ptr")
        commit_ptr = Signal(pb, name="commit_ptr")
        head = Signal(pb, name="head")
        offset = Const(0, pb)
        for valid, ray in finishing_out:
            port = fifo.write_port()
            m.d.comb += [
                port.addr.eq((stage_ptr + offset)[: pb - 1]),
                port.data.eq(ray),
                port.en.eq(valid),
            ]
            offset = offset + valid
        m.d.sync += stage_ptr.eq(stage_ptr + offset)
        samples = Signal(32, name="sample_count")
        m.d.sync += samples.eq(samples + sum(sample_out))
        m.d.comb += self.samples.eq(samples)

        # Commit: the rays of a period join the FIFO `latency` clocks after it ends.  The
        # stage pointer is sampled when the period's last sample has been written back.
        wheel = [Signal(pb + 1, name=f"commit_wheel{k}") for k in range(WHEEL)]
        snap_at = Signal(name="snapshot")
        end_d = seq["end"] & (seq["period"] >= 1)
        chain = []
        for d in range(ISSUE_TO_WRITEBACK + 1):
            nxt = Signal(name=f"end_d{d}")
            m.d.sync += nxt.eq(end_d)
            end_d = nxt
            chain.append(nxt)
        m.d.comb += snap_at.eq(end_d)
        snap_busy = Cat(*chain).any()
        # The last slot of a period issued at E - 1 is written back at E - 1 + 14: the
        # snapshot at E + 14 (end pulse at E - 1 delayed 15) sees all of them.
        # Inserted at position latency - (ISSUE_TO_WRITEBACK + 2) of a wheel that shifts
        # toward 0 each clock, read at 0: visible `latency` clocks after the period's end.
        insert_at = self.latency - (ISSUE_TO_WRITEBACK + 2)
        for k in range(WHEEL):
            nxt = wheel[k + 1] if k + 1 < WHEEL else Const(0, pb + 1)
            with m.If(snap_at & (insert_at == k)):
                # Writes of this cycle belong to the next period's slots.
                m.d.sync += wheel[k].eq(Cat(stage_ptr, Const(1, 1)))
            with m.Else():
                m.d.sync += wheel[k].eq(nxt)
        pending = Signal(name="commits_pending")
        m.d.comb += pending.eq(Cat(*[w[pb] for w in wheel]).any())
        with m.If(wheel[0][pb]):
            m.d.sync += commit_ptr.eq(wheel[0][:pb])

        # Drain: pop -> FIFO read (1 clock) -> compositing-buffer read (1 clock) -> output.
        advance = Signal(name="bus_advance")
        v1, v2 = Signal(name="bus_v1"), Signal(name="bus_v2")
        m.d.comb += advance.eq(~v2 | self.pixel.ready)
        pop = Signal(name="pop")
        m.d.comb += pop.eq(advance & (head != commit_ptr))
        fifo_rd = fifo.read_port()
        m.d.comb += [fifo_rd.addr.eq(head[: pb - 1]), fifo_rd.en.eq(advance)]
        pix_rd = ray_buffer.read_port()
        m.d.comb += [pix_rd.addr.eq(fifo_rd.data), pix_rd.en.eq(advance)]
        ray_out = Signal(geo.ray_bits, name="bus_ray")
        with m.If(advance):
            m.d.sync += [v1.eq(pop), v2.eq(v1), ray_out.eq(fifo_rd.data)]
        with m.If(pop):
            m.d.sync += head.eq(head + 1)
        entry = data.View(buffer_lay, pix_rd.data)
        m.d.comb += [
            self.pixel.valid.eq(v2),
            self.pixel.payload.ray.eq(ray_out),
            self.pixel.payload.acc.eq(entry.acc),
            self.pixel.payload.mip.eq(entry.mip),
        ]

        # Frame end: slices done, every commit made, FIFO empty.  `cycles` counts the
        # sequencer's clocks plus the bus's after it (first prime clock = 0).
        frame = Signal(name="frame")
        counted = Signal(name="counted")
        tail = Signal(32, name="tail_cycles")
        finished = ~pending & ~snap_at & ~snap_busy & (head == commit_ptr)
        with m.If(self.start):
            m.d.sync += [self.done.eq(0), samples.eq(0), counted.eq(0)]
        with m.If(seq["go"]):
            m.d.sync += [frame.eq(1), tail.eq(0)]
        with m.Elif(frame & ~seq["run"]):
            with m.If(finished):
                # The count stops at the last pop; `done` waits for the bus to deliver.
                m.d.sync += [frame.eq(0), counted.eq(1)]
            with m.Else():
                m.d.sync += tail.eq(tail + 1)
        with m.If(counted & ~v1 & ~v2):
            m.d.sync += [counted.eq(0), self.done.eq(1)]
        m.d.comb += self.cycles.eq(seq["cycle"] + tail)
        return m
