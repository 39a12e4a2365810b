"""The Cube-4 pipeline top: skewed volume memory, slice buffers, neighbour links, the
interpolator / gradient / classifier / shader / compositor chain of every pipeline, the
compositing buffer and the pixel bus, rendering a small volume end to end with the cycle
rung's timing.

# Ref: architectures.md sections 1.1-1.4 (Pfister & Kaufman, VolVis 1996: slice-parallel
#      ray casting on a skewed memory, local neighbour links, gradients from samples,
#      pixel bus) and 9.1-9.3 (units, buffer sizes, latencies); docs/cycle.md (the
#      timing rules reproduced).

Structure (``P`` pipelines, volumes up to ``N`` voxels per axis):

* **memory modules** (outside the chip, behind the ``vmem_*`` ports): module ``m`` holds
  the voxels ``(x, y, z)`` with ``(x + y + z) mod P = m`` at word ``(z ny + y) ceil(nx /
  P) + x div P`` (the cycle rung's layout); every clock the top presents one address per
  module and reads the voxel one clock later (a synchronous SRAM; ``vmem_en`` low holds
  the data while the core is frozen).
* **slice read**: in period ``p`` every pipeline reads one voxel of slice ``p`` per clock,
  in beam order: slot ``t = a C + g`` (``C = ceil(n_b / P)``) is voxel
  ``(a, b = P g + ((m - q - a) mod P))`` of slice ``q``, written to its slice buffer at
  ``t``.  Slice buffers hold four slices in four banks (the one filling and the three
  the evaluated step reads), so the first slice is read one period ahead of its samples
  (the cycle rung's priming slice).
* **sample slots** (:mod:`rtl.top_pipeline`): in period ``p`` pipeline ``m`` evaluates,
  in the same slot order ``C + 1`` clocks later, the cell of slice ``p - 1`` whose
  nearest voxel is its slot's voxel (the cycle rung's lane rule) on that slice and its
  two neighbours, then the gradient from the neighbouring samples one beam later,
  classification, shading (the datapath's method: per-sample Phong, or reflectance maps
  looked up by the gradient's direction) and compositing.
* **per-slice constants** (the host's geometry unit, parallel projection): slice index,
  cell shift ``(da, db)``, base-plane offset ``(ia, ib)`` and the quantised weights
  ``(wa, wb)`` of every step, in a table the host writes before the frame.  The ray table
  holds each base-plane ray's first and last step.
* **pixel bus**: when the compositor writes back a ray's last sample, the ray number is
  pushed into the pixel FIFO (several pipelines may push in one clock); the bus pops one
  per clock and sends the ray's accumulators through the ``pixel`` stream, which may be
  back-pressured.  When the FIFO has no room for a push (occupancy at ``fifo_depth``;
  several pushes in one clock go in pipeline order while there is room), the whole core
  (sequencer, memories, every pipeline register: one clock enable) freezes for that
  clock while the bus keeps draining; the push is retried the next clock.

Timing is the structure's: periods of ``T = n_a C`` clocks (computed here from the
geometry registers), the depth of the pipeline registers, the FIFO's pushes and pops
and the freezes.  The host loads no latency, period, overhead, per-slice count or
credit.  ``cycles`` counts from the first clock of the prime period to the last pixel
popped from the pixel FIFO (or to the sequencer's last clock if that is later).
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth import Array, Cat, Const, EnableInserter, Module, Mux, Signal, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from models.datapath import Datapath
from rtl.common import bit_length, divide_by_constant
from rtl.composite import LATENCY as COMPOSITE_LATENCY
from rtl.gradient import RATIO_BITS
from rtl.shade import COEF_BITS
from rtl.top_layouts import (
    LOAD_RAYS,
    LOAD_SLICES,
    TopGeometry,
    buffer_layout,
    load_layout,
    pixel_layout,
    ray_layout,
    slice_layout,
)
from rtl.top_pipeline import EVAL_BASE, MAX_LIGHTS, STAGE_BASE, back_end, front_end, modulo

# The load targets and word layouts are rtl.top_layouts'; the pipeline stages rtl.top_pipeline's.
__all__ = ["Cube4Top", "TopConfig", "RMW_WINDOW"]

#: Clocks between a ray's compositing-buffer read and its write becoming visible: the
#: read one clock ahead, the compositor's ``LATENCY``, the write.
RMW_WINDOW = COMPOSITE_LATENCY + 2
#: Clocks the core needs at most to empty after the sequencer's last slot, beyond ``2
#: C_max``: the slot delay (``C + EVAL_BASE``), the front end, the beam wait (``C``) and
#: the back end (``STAGE_BASE``), the compositor and write-back; a bound, not a timing
#: value: the frame's ``cycles`` stop at the last pixel popped.
DRAIN_BOUND = STAGE_BASE + COMPOSITE_LATENCY + 5


def _phong_ports(dp: Datapath) -> dict:
    """The per-sample Phong shader's registers (a reflectance-map shader has none: its
    lights are in the maps the host loads)."""
    vectors = MAX_LIGHTS * 3 * (dp.shade.normal_frac_bits + 2)
    return {
        "kd": In(COEF_BITS),
        "ks": In(COEF_BITS),
        "light": In(vectors),
        "half": In(vectors),
        "intensity": In(MAX_LIGHTS * COEF_BITS),
    }


@dataclass(frozen=True, kw_only=True)
class TopConfig:
    """``hwsim rtl build top`` parameters: pipelines, largest volume, voxel width (the
    unit formats are the defaults; a frame's own datapath comes from its machine)."""

    pipelines: int = 4
    max_axis: int = 16
    voxel_bits: int = 12

    def __post_init__(self):
        for name, lo, hi in (("pipelines", 1, 16), ("max_axis", 4, 128), ("voxel_bits", 1, 16)):
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise ValueError(f"{name} {lo}..{hi}")

    def build(self) -> Cube4Top:
        return Cube4Top(
            Datapath(voxel_bits=self.voxel_bits), TopGeometry(self.pipelines, self.max_axis)
        )


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
        Host writes (:func:`load_layout`) before a frame: tables, not the volume.
    vmem_addr, vmem_en : Out; vmem_data : In
        The voxel memory outside the chip: module ``k``'s word address at bits ``k A``
        (``A = geo.module_addr_bits``) and its voxel, one clock later, at bits ``k B`` of
        ``vmem_data``; ``vmem_en`` low: hold the read data (the core is frozen).
    start : In(1)
        Pulse: render one frame with the registers below.
    n_kp, n_a, n_b, nx, ny, cx, kp, forward, c, fifo_depth, width, height, mip, ert_enable,
    ert_threshold : In
        Frame registers: slice and in-slice sizes, the volume's ``nx``, ``ny`` and
        ``ceil(nx / P)``, the principal axis (0 z, 1 y, 2 x), slice order (1: increasing
        index), ``C``, the pixel FIFO's usable depth (rule 4), base-plane width and height,
        MIP mode, early termination.  No timing value: the period ``T = n_a C`` is computed
        here, latencies are the pipeline's own.
    crop, crop_needed, crop_invert : In
        The crop box on: a sample is composited when it lies inside ``crop_needed`` of the
        three slabs (sub-volume 3, cross 2, fence 1), or outside with ``crop_invert``;
        the slabs per slice are in the slice table.  A cropped sample's ray still
        leaves on the pixel bus after its last step.
    lit, modulate, gm_scale, ratio, ka : In
        Shading on, gradient-magnitude opacity modulation on and its UQ0.24 index scale,
        the gradient's ``to_world`` ratios (3 x UQ1.12, x first), the ambient coefficient
        (UQ4.8).
    kd, ks, light, half, intensity : In, per-sample Phong only
        The Phong coefficients (UQ4.8) and ``MAX_LIGHTS`` lights (``light``, ``half``: 3
        SQ1.F components each, light 0 and x first; ``intensity`` UQ4.8; an unused light
        has intensity 0).  With ``dp.shade.method = "reflectance-map"`` (VolumePro 500)
        the shader reads the diffuse and specular maps the host loads instead, any number
        of lights summed in them.
    pixel : Out stream
        :func:`pixel_layout` (back-pressure allowed).
    busy, done : Out(1)
        A frame is running / has finished (``done`` holds until the next ``start``).
    cycles, samples, stall_cycles : Out(32)
        The frame's clocks (first prime clock to the last pixel popped), samples
        composited and clocks the core was frozen by a full pixel FIFO.
    frame_clock : Out(32); frozen, period_start : Out(1)
        Status for traces and ``hwsim rtl diff``: the clock of the frame (0 = the prime
        period's first), the core frozen in this clock, a period's first slot issued.
    read_slice, read_row : Out; read_valid, read_last : Out(1)
        The slot the memory read serves this clock: slice ``q``, row ``a``, a read this
        clock, the row's last slot (the vg500 top holds the core until its SDRAM front
        end has delivered the voxels: ``rtl/vg500/top.py``).
    """

    def __init__(self, dp: Datapath, geo: TopGeometry):
        self.dp, self.geo = dp, geo
        ab = geo.axis_bits
        super().__init__(
            {
                "load": In(stream.Signature(load_layout(geo, dp), always_ready=True)),
                "vmem_addr": Out(geo.pipelines * geo.module_addr_bits),
                "vmem_en": Out(1),
                "vmem_data": In(geo.pipelines * dp.voxel_bits),
                "start": In(1),
                "n_kp": In(ab),
                "n_a": In(ab),
                "n_b": In(ab),
                "nx": In(ab),
                "ny": In(ab),
                "cx": In(ab),
                "kp": In(2),
                "forward": In(1),
                "c": In(ab),
                "fifo_depth": In(32),
                "width": In(bit_length(2 * geo.max_axis)),
                "height": In(bit_length(2 * geo.max_axis)),
                "mip": In(1),
                "ert_enable": In(1),
                "ert_threshold": In(dp.composite.acc_frac_bits + 1),
                "crop": In(1),
                "crop_needed": In(2),
                "crop_invert": In(1),
                "lit": In(1),
                "modulate": In(1),
                "gm_scale": In(32),
                "ratio": In(3 * (RATIO_BITS + 1)),
                "ka": In(COEF_BITS),
                **(_phong_ports(dp) if dp.shade.method == "phong" else {}),
                "pixel": Out(stream.Signature(pixel_layout(geo, dp))),
                "busy": Out(1),
                "done": Out(1),
                "cycles": Out(32),
                "samples": Out(32),
                "stall_cycles": Out(32),
                "frame_clock": Out(32),
                "frozen": Out(1),
                "period_start": Out(1),
                "read_slice": Out(ab),
                "read_row": Out(ab),
                "read_valid": Out(1),
                "read_last": Out(1),
            }
        )

    # ------------------------------------------------------------------ sequencer

    def _sequencer(self, m: Module, slices):
        """Periods ``p = 0 .. n_kp`` of ``T = n_a C`` clocks; slot counters."""
        geo = self.geo
        ab = geo.axis_bits
        P = geo.pipelines
        s = {
            "run": Signal(name="run"),
            "period": Signal(ab + 1, name="period"),
            "tick": Signal(bit_length(geo.t_max), name="tick"),
            "a": Signal(ab, name="slot_a"),
            "g": Signal(ab, name="slot_g"),
            "amod": Signal(bit_length(P), name="slot_amod"),
        }
        t = Signal(bit_length(geo.t_max), name="slice_clocks")
        m.d.comb += t.eq(self.n_a * self.c)
        lay = slice_layout(geo, self.dp)
        mem_c = Signal(lay, name="mem_consts")  # slice read in this period (p)
        eval_c = Signal(lay, name="eval_consts")  # slice evaluated (p - 1)
        prefetch = slices.read_port()
        m.d.comb += [prefetch.addr.eq(s["period"] + 1), prefetch.en.eq(1)]
        setup = Signal(2, name="setup")
        end = Signal(name="period_end")
        m.d.comb += end.eq(s["run"] & (s["tick"] == t - 1))
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
                mem_c.eq(first.data),
            ]
        with m.If(s["run"]):
            m.d.sync += s["tick"].eq(s["tick"] + 1)
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
                    eval_c.eq(mem_c),
                    mem_c.eq(prefetch.data),
                ]
                with m.If(s["period"] == self.n_kp):
                    m.d.sync += s["run"].eq(0)
        s["mem_valid"] = Signal(name="mem_valid")
        s["eval_valid"] = Signal(name="eval_valid")
        m.d.comb += [
            s["mem_valid"].eq(s["run"] & (s["period"] < self.n_kp)),
            s["eval_valid"].eq(s["run"] & (s["period"] >= 1)),
        ]
        s["end"] = end
        s["go"] = setup == 2
        s["mem_c"], s["eval_c"] = mem_c, eval_c
        return s

    # ------------------------------------------------------------------ elaborate

    def elaborate(self, platform):
        m = Module()
        # Everything but the compositing buffer and the pixel bus is the core: one clock
        # enable freezes it while a push into the pixel FIFO does not fit.
        core = Module()
        stall = Signal(name="pixel_fifo_stall")
        dp, geo = self.dp, self.geo
        P, ab = geo.pipelines, geo.axis_bits
        B = dp.voxel_bits
        load = self.load.payload

        def loading(target):
            return self.load.valid & (load.target == target)

        # Tables the host writes.
        core.submodules.slices = slices = Memory(
            shape=slice_layout(geo, dp), depth=geo.max_axis + 2, init=[]
        )
        wr = slices.write_port()
        core.d.comb += [
            wr.addr.eq(load.addr),
            wr.data.eq(load.data),
            wr.en.eq(loading(LOAD_SLICES)),
        ]
        core.submodules.rays = rays = Memory(shape=ray_layout(geo), depth=geo.max_rays, init=[])
        wr = rays.write_port()
        core.d.comb += [
            wr.addr.eq(load.addr),
            wr.data.eq(load.data),
            wr.en.eq(loading(LOAD_RAYS)),
        ]

        seq = self._sequencer(core, slices)
        m.d.comb += self.busy.eq(seq["run"])

        # ---------------------------------------------------------- memory -> slice buffers
        # Each pipeline's slice buffer: four banks of one slice each (period p fills bank
        # p mod 4 while step p - 1 reads the banks of slices q - 1, q and q + 1).
        bufs = []
        mem_c = seq["mem_c"]
        aw = geo.module_addr_bits
        m.d.comb += self.vmem_en.eq(~stall)
        # The slot read this clock, for a memory that may not have the voxel yet (vg500).
        m.d.comb += [
            self.read_slice.eq(mem_c.q),
            self.read_row.eq(seq["a"]),
            self.read_valid.eq(seq["mem_valid"]),
            self.read_last.eq(seq["g"] == self.c - 1),
        ]
        for k in range(P):
            # Slot voxel of this pipeline: b = P g + ((k - q - a) mod P).
            r = Signal(bit_length(P), name=f"read_r{k}")
            core.d.comb += r.eq(modulo(k + 2 * P - mem_c.qm - seq["amod"], P, 3 * P))
            a, b = seq["a"], Signal(ab + 1, name=f"read_b{k}")
            core.d.comb += b.eq(seq["g"] * P + r)
            q = mem_c.q
            z = Mux(self.kp == 0, q, a)
            y = Mux(self.kp == 0, a, Mux(self.kp == 1, q, b))
            x = Mux(self.kp == 2, q, b)
            addr = (z * self.ny + y) * self.cx + divide_by_constant(x, P, ab + 1)
            core.d.comb += self.vmem_addr[k * aw : (k + 1) * aw].eq(addr)
            voxel = self.vmem_data[k * B : (k + 1) * B]
            read_valid = Signal(name=f"read_valid{k}")
            core.d.comb += read_valid.eq(seq["mem_valid"] & (b < self.n_b))
            # One clock later the voxel arrives; it is written at its slot.
            wslot = Signal(range(geo.t_max), name=f"write_slot{k}")
            wbank = Signal(2, name=f"write_bank{k}")
            wvalid = Signal(name=f"write_valid{k}")
            core.d.sync += [
                wslot.eq(seq["a"] * self.c + seq["g"]),
                wbank.eq(seq["period"][:2]),
                wvalid.eq(read_valid),
            ]
            banks = []
            for bank in range(4):
                buf = Memory(shape=unsigned(B), depth=geo.t_max, init=[])
                core.submodules[f"slice_buffer_{k}_{bank}"] = buf
                bw = buf.write_port()
                core.d.comb += [
                    bw.addr.eq(wslot),
                    bw.data.eq(voxel),
                    bw.en.eq(wvalid & (wbank == bank)),
                ]
                banks.append((buf, bw))
            bufs.append(banks)

        # ---------------------------------------------------------- sample slots
        # The sequencer's slot, C + EVAL_BASE clocks later: the next slice's voxel at the
        # cell's far corner (read at most C + 1 clocks after the slot) is then written.
        slot = Cat(seq["a"], seq["g"], seq["amod"], seq["eval_valid"], seq["period"])
        packed = Cat(slot, seq["eval_c"].as_value())
        chain = [packed]
        for d in range(geo.c_max + EVAL_BASE):
            nxt = Signal(len(packed), name=f"slot_d{d}")
            core.d.sync += nxt.eq(chain[-1])
            chain.append(nxt)
        ev_slot = Signal(len(packed), name="eval_slot")
        core.d.comb += ev_slot.eq(Array(chain)[self.c + EVAL_BASE])
        pos, fields = 0, {}
        for name, width in (
            ("a", ab),
            ("g", ab),
            ("amod", bit_length(P)),
            ("valid", 1),
            ("period", ab + 1),
        ):
            fields[name] = ev_slot[pos : pos + width]
            pos += width
        fields["valid"] = fields["valid"][0]
        fields["consts"] = data.View(slice_layout(geo, dp), ev_slot[pos:])

        # The compositing buffer is outside the core: the pixel bus reads it while the
        # core is frozen.
        buffer_lay = buffer_layout(dp)
        m.submodules.ray_buffer = ray_buffer = Memory(shape=buffer_lay, depth=geo.max_rays, init=[])
        fronts = [front_end(core, self, k, fields, bufs, rays) for k in range(P)]
        backs = [
            back_end(core, self, k, fronts, ray_buffer, buffer_lay, loading, ~stall)
            for k in range(P)
        ]
        self._buffer_writes(m, ray_buffer, buffer_lay, backs, loading(LOAD_RAYS))
        samples = Signal(32, name="sample_count")
        with core.If(self.start):
            core.d.sync += samples.eq(0)
        with core.Else():
            core.d.sync += samples.eq(samples + sum(back["counted"] for back in backs))
        m.d.comb += self.samples.eq(samples)
        # After the last period the core empties within a bound of its own depth.
        draining = Signal(range(2 * geo.c_max + DRAIN_BOUND + 1), name="core_draining")
        with core.If(seq["end"] & (seq["period"] == self.n_kp)):
            core.d.sync += draining.eq(2 * geo.c_max + DRAIN_BOUND)
        with core.Elif(draining != 0):
            core.d.sync += draining.eq(draining - 1)
        core_busy = seq["run"] | (draining != 0)
        m.submodules.core = EnableInserter(~stall)(core)
        self._pixel_bus(m, seq, ray_buffer, buffer_lay, backs, stall, core_busy)
        return m

    def _buffer_writes(self, m, ray_buffer, buffer_lay, backs, clearing):
        """One write port per compositor; the host's clear (a ray's entry zeroed and
        alive, while loading the rays, never during a frame) shares pipeline 0's, the
        compositor first.  One write port is what lets a block RAM hold the buffer: with
        the clear on a port of its own, Yosys built the 8^3 top's from 21 760 flip-flops
        (docs/rtl.md, "On a real FPGA"); its two read ports then cost one copy each."""
        load = self.load.payload
        cleared = Cat(Const(0, buffer_lay.size - 1), Const(1, 1))
        for k, back in enumerate(backs):
            addr, wdata, en = back["write"]
            port = ray_buffer.write_port()
            m.d.comb += [port.addr.eq(addr), port.data.eq(wdata), port.en.eq(en)]
            if k == 0:
                with m.If(~en & clearing):
                    m.d.comb += [
                        port.addr.eq(load.addr),
                        port.data.eq(cleared),
                        port.en.eq(1),
                    ]

    # ------------------------------------------------------------------ pixel bus

    def _pixel_bus(self, m, seq, ray_buffer, buffer_lay, backs, stall, core_busy):
        """The pixel FIFO (pushes, the freeze when they do not fit), its drain and the
        frame's end."""
        geo = self.geo
        ram = 1 << bit_length(geo.max_rays - 1)  # a power of two: pointers wrap cleanly
        pb = bit_length(ram)  # pointers carry one wrap bit
        m.submodules.pixel_fifo = fifo = Memory(shape=unsigned(geo.ray_bits), depth=ram, init=[])
        tail = Signal(pb, name="fifo_tail")
        head = Signal(pb, name="fifo_head")
        occupancy = Signal(pb, name="fifo_occupancy")
        m.d.comb += occupancy.eq(tail - head)
        usable = Signal(32, name="fifo_usable")
        m.d.comb += usable.eq(Mux(self.fifo_depth > ram, ram, self.fifo_depth))
        room = Signal(pb + 1, name="fifo_room")
        m.d.comb += room.eq(Mux(usable > occupancy, usable - occupancy, 0))
        # Each compositor holds its ray until the FIFO takes it; in a clock with too little
        # room the lower pipelines go first and the core freezes (the ones taken are
        # remembered, so a frozen compositor's push is not repeated).
        taken_before = Const(0, pb + 1)
        refused = []
        for k, back in enumerate(backs):
            done = Signal(name=f"push_done{k}")
            pending = Signal(name=f"push_pending{k}")
            accept = Signal(name=f"push_accept{k}")
            m.d.comb += [
                pending.eq(back["push"] & ~done),
                accept.eq(pending & (taken_before < room)),
            ]
            port = fifo.write_port()
            m.d.comb += [
                port.addr.eq((tail + taken_before)[: pb - 1]),
                port.data.eq(back["ray"]),
                port.en.eq(accept),
            ]
            m.d.sync += done.eq(stall & (done | accept))
            refused.append(pending & ~accept)
            taken_before = taken_before + accept
        m.d.comb += stall.eq(Cat(*refused).any())
        m.d.sync += tail.eq(tail + taken_before)

        # Drain: pop -> FIFO read (1 clock) -> compositing-buffer read (1 clock) -> output.
        advance = Signal(name="bus_advance")
        v1, v2 = Signal(name="bus_v1"), Signal(name="bus_v2")
        m.d.comb += advance.eq(~v2 | self.pixel.ready)
        pop = Signal(name="pop")
        m.d.comb += pop.eq(advance & (head != tail))
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

        # The frame's clocks: from the first prime clock (0) to the last pixel popped, or
        # to the sequencer's last clock if no pixel leaves after it.
        frame = Signal(name="frame")
        clock = Signal(32, name="frame_clock")
        last_pop = Signal(32, name="last_pop")
        seq_end = Signal(32, name="sequencer_end")
        stalls = Signal(32, name="stall_count")
        with m.If(self.start):
            m.d.sync += self.done.eq(0)
        with m.If(seq["go"]):
            m.d.sync += [
                frame.eq(1),
                clock.eq(0),
                last_pop.eq(0),
                seq_end.eq(0),
                stalls.eq(0),
            ]
        with m.Elif(frame):
            m.d.sync += [clock.eq(clock + 1), stalls.eq(stalls + stall)]
            with m.If(pop):
                m.d.sync += last_pop.eq(clock + 1)
            with m.If(seq["run"]):
                m.d.sync += seq_end.eq(clock + 1)
            with m.If(~seq["run"] & ~core_busy & (head == tail) & ~v1 & ~v2):
                m.d.sync += [frame.eq(0), self.done.eq(1)]
        m.d.comb += [
            self.cycles.eq(Mux(last_pop > seq_end, last_pop, seq_end)),
            self.stall_cycles.eq(stalls),
            self.frame_clock.eq(clock),
            self.frozen.eq(stall),
            self.period_start.eq(seq["run"] & (seq["tick"] == 0) & ~stall),
        ]
