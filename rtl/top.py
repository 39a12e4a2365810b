"""The Cube-4 pipeline top: skewed volume memory, slice buffers, neighbour links, the
interpolator / gradient / classifier / shader / compositor chain of every pipeline, the
compositing buffer and the pixel bus, rendering a small volume end to end with the cycle
rung's timing.

# Ref: architectures.md sections 1.1-1.4 (Pfister & Kaufman, VolVis 1996: slice-parallel
#      ray casting on a skewed memory, local neighbour links, gradients from samples,
#      pixel bus) and 9.1-9.3 (units, buffer sizes, latencies); docs/cycle.md (the
#      timing rules reproduced).

Structure (``P`` pipelines, volumes up to ``N`` voxels per axis):

* **memory modules**: module ``m`` holds the voxels ``(x, y, z)`` with
  ``(x + y + z) mod P = m`` at word ``(z ny + y) ceil(nx / P) + x div P`` (the cycle
  rung's layout); the host writes them through the wide ``load`` port (P voxels a word).
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
  classification, Phong shading and compositing.
* **per-slice constants** (the host's geometry unit, parallel projection): slice index,
  cell shift ``(da, db)``, base-plane offset ``(ia, ib)``, the quantised weights
  ``(wa, wb)`` and the count of rays finishing, of every step, in a table the host
  writes before the frame.  The ray table holds each base-plane ray's first and last
  step.
* **pixel bus**: a ray whose last sample enters the compositor joins the pixel FIFO; the
  rays of slice period ``p`` are committed ``latency`` clocks after the period's block
  ends (the machine's pipeline latency, rule 5 of docs/cycle.md) and drained one per
  clock through the ``pixel`` stream (ray number, accumulators), which may be
  back-pressured.

Timing: the prime period takes ``T = n_a C`` clocks, every other ``T +
slice_overhead`` plus the rule-4 stall when the pixel FIFO (as the rule sees it: a
credit counter) has no room for the period's finishing rays; ``cycles`` counts from the
first clock of the prime period to the last pixel popped from the pixel FIFO, which is
rules 1, 2, 4, 5 and 6 of the cycle rung for parallel views (no stretch: that needs
perspective).
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth import Array, Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from models.datapath import Datapath
from rtl.common import bit_length, divide_by_constant
from rtl.gradient import RATIO_BITS
from rtl.shade import COEF_BITS
from rtl.top_layouts import (
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
from rtl.top_pipeline import EVAL_BASE, MAX_LIGHTS, STAGE_BASE, back_end, front_end, modulo

# The load targets and word layouts are rtl.top_layouts'; the pipeline stages rtl.top_pipeline's.
__all__ = [
    "Cube4Top",
    "TopConfig",
    "issue_to_stage",
    "issue_to_writeback",
    "RMW_WINDOW",
]

#: Clocks between a ray's compositing-buffer read and its write becoming visible.
RMW_WINDOW = 5
WHEEL = 64  # commit delay line: latency - (2 C + 18) < 64 clocks
II = 1


def issue_to_stage(beam_cycles: int) -> int:
    """Clocks from a sample slot's issue to its sample entering the compositor (where a
    finishing ray is staged for the pixel bus): ``2 C + 16``."""
    return 2 * beam_cycles + STAGE_BASE


def issue_to_writeback(beam_cycles: int) -> int:
    """Clocks from a sample slot's issue to the compositor's answer: ``2 C + 19``."""
    return issue_to_stage(beam_cycles) + 3


#: A sample slot's issue to its compositor answer for one clock per beam (``C = 1``);
#: each clock of ``C`` adds two (the evaluation wait and the gradient look-ahead).
LATENCY = issue_to_writeback(1)


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
    n_kp, n_a, n_b, nx, ny, cx, kp, forward, c, t, overhead, latency, width, height, mip,
    ert_enable, ert_threshold : In
        Frame registers: slice and in-slice sizes, the volume's ``nx``, ``ny`` and
        ``ceil(nx / P)``, the principal axis (0 z, 1 y, 2 x), slice order (1: increasing
        index), ``C``, ``T``, slice overhead and pipeline latency (clocks), the pixel
        FIFO's depth (rule 4), base-plane width and height, MIP mode, early termination.
    lit, modulate, gm_scale, ratio, ka, kd, ks, light, half, intensity : In
        Shading on, gradient-magnitude opacity modulation on and its UQ0.24 index scale,
        the gradient's ``to_world`` ratios (3 x UQ1.12, x first), the Phong coefficients
        (UQ4.8) and ``MAX_LIGHTS`` lights (``light``, ``half``: 3 SQ1.F components each,
        light 0 and x first; ``intensity`` UQ4.8; an unused light has intensity 0).
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
                "forward": In(1),
                "c": In(ab),
                "t": In(bit_length(geo.t_max)),
                "overhead": In(16),
                "fifo_depth": In(32),
                "latency": In(8),
                "width": In(bit_length(2 * geo.max_axis)),
                "height": In(bit_length(2 * geo.max_axis)),
                "mip": In(1),
                "ert_enable": In(1),
                "ert_threshold": In(dp.composite.acc_frac_bits + 1),
                "lit": In(1),
                "modulate": In(1),
                "gm_scale": In(32),
                "ratio": In(3 * (RATIO_BITS + 1)),
                "ka": In(COEF_BITS),
                "kd": In(COEF_BITS),
                "ks": In(COEF_BITS),
                "light": In(MAX_LIGHTS * 3 * (dp.shade.normal_frac_bits + 2)),
                "half": In(MAX_LIGHTS * 3 * (dp.shade.normal_frac_bits + 2)),
                "intensity": In(MAX_LIGHTS * COEF_BITS),
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
        # Rule 4: the pixel FIFO as the cycle rung's timing sees it (the rays of a step
        # join at its block's end, one leaves per clock) is a credit counter; a step whose
        # finishing rays do not fit stalls the sequencer until the bus has made room.
        # The FIFO itself fills `latency` clocks later, with the same pops.
        block_end = Signal(name="block_end")
        m.d.comb += block_end.eq(s["run"] & (s["tick"] == period_len - 1))
        credit = Signal(32, name="pixel_credit")
        drained = Signal(32, name="pixel_credit_drained")
        arrivals = Signal(32, name="pixel_arrivals")
        stall_now = Signal(32, name="pixel_stall")
        m.d.comb += [
            drained.eq(Mux(credit > 0, credit - 1, 0)),
            arrivals.eq(Mux(s["period"] >= 1, eval_c.finish, 0)),
            stall_now.eq(
                Mux(arrivals + drained > self.fifo_depth, arrivals + drained - self.fifo_depth, 0)
            ),
        ]
        stalling = Signal(name="pixel_stalling")
        stall_left = Signal(32, name="pixel_stall_left")
        end = Signal(name="period_end")
        m.d.comb += end.eq((block_end & (stall_now == 0)) | (stalling & (stall_left == 1)))
        with m.If(s["run"]):
            m.d.sync += credit.eq(Mux(block_end, drained + arrivals, drained))
            with m.If(block_end & (stall_now != 0)):
                m.d.sync += [stalling.eq(1), stall_left.eq(stall_now)]
            with m.Elif(stalling):
                m.d.sync += stall_left.eq(stall_left - 1)
                with m.If(stall_left == 1):
                    m.d.sync += stalling.eq(0)
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
                s["cycle"].eq(0),
                mem_c.eq(first.data),
                credit.eq(0),
                stalling.eq(0),
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
        s["end"], s["block_end"] = end, block_end
        s["go"] = setup == 2
        s["mem_c"], s["eval_c"] = mem_c, eval_c
        return s

    # ------------------------------------------------------------------ elaborate

    def elaborate(self, platform):
        m = Module()
        dp, geo = self.dp, self.geo
        P, ab = geo.pipelines, geo.axis_bits
        B = dp.voxel_bits
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
        # Each pipeline's slice buffer: four banks of one slice each (period p fills bank
        # p mod 4 while step p - 1 reads the banks of slices q - 1, q and q + 1).
        bufs = []
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
            m.d.comb += r.eq(modulo(k + 2 * P - mem_c.qm - seq["amod"], P, 3 * P))
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
            wslot = Signal(range(geo.t_max), name=f"write_slot{k}")
            wbank = Signal(2, name=f"write_bank{k}")
            wvalid = Signal(name=f"write_valid{k}")
            m.d.sync += [
                wslot.eq(seq["a"] * self.c + seq["g"]),
                wbank.eq(seq["period"][:2]),
                wvalid.eq(read_valid),
            ]
            banks = []
            for bank in range(4):
                buf = Memory(shape=unsigned(B), depth=geo.t_max, init=[])
                m.submodules[f"slice_buffer_{k}_{bank}"] = buf
                bw = buf.write_port()
                m.d.comb += [
                    bw.addr.eq(wslot),
                    bw.data.eq(rd.data),
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
            m.d.sync += nxt.eq(chain[-1])
            chain.append(nxt)
        ev_slot = Signal(len(packed), name="eval_slot")
        m.d.comb += ev_slot.eq(Array(chain)[self.c + EVAL_BASE])
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

        buffer_lay = buffer_layout(dp)
        m.submodules.ray_buffer = ray_buffer = Memory(shape=buffer_lay, depth=geo.max_rays, init=[])
        clear = ray_buffer.write_port()
        m.d.comb += [
            clear.addr.eq(load.addr),
            clear.data.eq(Cat(Const(0, buffer_lay.size - 1), Const(1, 1))),
            clear.en.eq(loading(LOAD_RAYS)),
        ]
        fronts = [front_end(m, self, k, fields, bufs, rays) for k in range(P)]
        backs = [back_end(m, self, k, fronts, ray_buffer, buffer_lay, loading) for k in range(P)]
        self._pixel_bus(m, seq, ray_buffer, buffer_lay, backs)
        return m

    # ------------------------------------------------------------------ pixel bus

    def _pixel_bus(self, m, seq, ray_buffer, buffer_lay, backs):
        """Staging, the commit wheel (rule 5), the drain and the frame's end."""
        geo = self.geo
        depth = geo.max_rays
        pb = bit_length(depth)  # pointers carry one wrap bit
        m.submodules.pixel_fifo = fifo = Memory(shape=unsigned(geo.ray_bits), depth=depth, init=[])
        stage_ptr = Signal(pb, name="stage_ptr")
        commit_ptr = Signal(pb, name="commit_ptr")
        head = Signal(pb, name="head")
        offset = Const(0, pb)
        for back in backs:
            port = fifo.write_port()
            m.d.comb += [
                port.addr.eq((stage_ptr + offset)[: pb - 1]),
                port.data.eq(back["ray"]),
                port.en.eq(back["stage"]),
            ]
            offset = offset + back["stage"]
        m.d.sync += stage_ptr.eq(stage_ptr + offset)
        samples = Signal(32, name="sample_count")
        m.d.sync += samples.eq(samples + sum(back["counted"] for back in backs))
        m.d.comb += self.samples.eq(samples)

        # Commit: the rays of a period join the FIFO `latency` clocks after it ends.  The
        # stage pointer is sampled when the period's last sample has been staged: a slot
        # issued at the period's last clock E - 1 is staged at E - 1 + S (S =
        # issue_to_stage(C)), so the end pulse delayed S + 1 sees all of them.
        wheel = [Signal(pb + 1, name=f"commit_wheel{k}") for k in range(WHEEL)]
        end_d = seq["block_end"] & (seq["period"] >= 1)
        chain = []
        for d in range(2 * geo.c_max + STAGE_BASE + 1):
            nxt = Signal(name=f"end_d{d}")
            m.d.sync += nxt.eq(end_d)
            end_d = nxt
            chain.append(nxt)
        tap = Signal(range(len(chain)), name="snapshot_tap")
        m.d.comb += tap.eq((self.c << 1) + STAGE_BASE)
        snap_at = Signal(name="snapshot")
        m.d.comb += snap_at.eq(Array(chain)[tap])
        snap_busy = Cat(*[x & (tap >= d) for d, x in enumerate(chain)]).any()
        # Inserted at position latency - (S + 2) of a wheel that shifts toward 0 each
        # clock, read at 0: visible `latency` clocks after the period's end.
        insert_at = Signal(signed(10), name="insert_at")
        m.d.comb += insert_at.eq(self.latency - tap - 2)
        for k in range(WHEEL):
            nxt = wheel[k + 1] if k + 1 < WHEEL else Const(0, pb + 1)
            with m.If(snap_at & (insert_at == k)):
                # Stagings of this cycle belong to the next period's slots.
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
