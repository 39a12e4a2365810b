"""One Cube-4 pipeline of the RTL top (:mod:`rtl.top`): its sample slot, slice-buffer
reads, the slice interpolator, the gradient from neighbouring samples, classification,
shading and compositing.

# Ref: architectures.md section 1.3 items 4-7 (interpolation between slices from delay
#      buffers and the neighbouring pipelines; gradients by central differences of
#      interpolated samples of beams j-1..j+1 and slices k-1..k+1; classification, Phong
#      shading, compositing buffers); section 3 (VolumePro 500's reflectance maps);
#      docs/cycle.md timing rule 5 (the look-ahead).

A pipeline evaluates one cell per slot.  Slot ``t`` of the step's period is evaluated ``C
+ 1`` clocks after the sequencer issued it (so the next slice's voxels of the cell's far
corner, read from memory at ``t + C + 1`` at the latest, are in the slice buffer):

* **address stage** (E0 -> E1, ``ADDRESS_LATENCY`` clocks): cell ``(a - da, b - db)``,
  corners clamped to the volume, the in-bank address of each corner and which
  neighbouring pipeline's buffer (offset ``-2 .. 2``) holds it: the skewed memory's
  address and de-skew, computed here for the slice buffers rather than by
  :class:`~rtl.skew.Skew` (docs/rtl.md), and given the skew unit's stage plan
  (``rtl.skew.LATENCY``: the cycle rung's ``skew.LATENCY`` of timing rule 5; its first
  clock the registers below, the others plain delay registers);
* **buffer stage** (E1 -> E2): the four corners on the slices ``q - 1``, ``q``, ``q + 1``
  (each buffer keeps four slices in four banks; the period picks which bank is which
  slice; the slice being filled is read through a transparent port) and the ray table;
* :class:`~rtl.slice_interp.SliceInterp` (its ``LATENCY``): the sample on the three slices and
  the edge lerps;
* **sample beam FIFO**: each pipeline keeps its last ``2 C_max + 1`` samples of slice
  ``q``; ``C`` clocks after a sample (one beam: the gradient look-ahead) its four in-slice
  neighbours exist: the next beam's from pipeline ``m + 1`` just now, the previous beam's
  from pipeline ``m - 1`` ``2 C`` clocks ago, the beam neighbours from pipelines ``m +- 1``
  ``C``, ``C -+ 1`` clocks ago; a neighbour beyond the volume's edge is the sample's own
  edge lerp;
* :class:`~rtl.gradient.Gradient` -> :class:`~rtl.classify.Classify` with
  gradient-magnitude modulation -> :class:`~rtl.shade.Shade` (the datapath's method:
  per-sample Phong, or the VolumePro 500's reflectance maps, loaded by the host; one
  ``LATENCY`` for both) -> :class:`~rtl.composite.Composite` (each its own ``LATENCY``,
  the length of its RTL stage plan), the compositing buffer read one clock before the
  compositor and written when it answers.
"""

from __future__ import annotations

from amaranth import Array, Cat, Const, Module, Mux, Signal, signed
from amaranth.lib import data

from rtl.classify import LATENCY as CLASSIFY_LATENCY
from rtl.classify import Classify
from rtl.common import divide_by_constant
from rtl.composite import LATENCY as COMPOSITE_LATENCY
from rtl.composite import Composite
from rtl.gradient import LATENCY as GRADIENT_LATENCY
from rtl.gradient import RATIO_BITS, Gradient
from rtl.shade import COEF_BITS, Shade
from rtl.shade import LATENCY as SHADE_LATENCY
from rtl.skew import LATENCY as ADDRESS_LATENCY
from rtl.slice_interp import LATENCY as SLICE_LATENCY
from rtl.slice_interp import SliceInterp
from rtl.top_layouts import (
    LOAD_CORRECTION,
    LOAD_DIFFUSE_MAP,
    LOAD_GM,
    LOAD_LUT,
    LOAD_SPEC,
    ray_layout,
)

__all__ = [
    "PipelineFrontEnd",
    "front_end",
    "back_end",
    "modulo",
    "ADDRESS_LATENCY",
    "EVAL_BASE",
    "STAGE_BASE",
    "MAX_LIGHTS",
]

#: Slot issue -> address stage is ``C + EVAL_BASE`` clocks (the next slice's far corner).
EVAL_BASE = 1
#: Slot issue -> the sample enters the compositor: ``2 C + STAGE_BASE`` (address
#: ``ADDRESS_LATENCY``, buffer 1, the slice interpolator, look-ahead C, gradient, classify,
#: shade: each unit's own ``LATENCY``, its RTL stage plan).
STAGE_BASE = (
    EVAL_BASE
    + ADDRESS_LATENCY
    + 1
    + SLICE_LATENCY
    + GRADIENT_LATENCY
    + CLASSIFY_LATENCY
    + SHADE_LATENCY
)
#: Directional lights the shader sums (unused ones have intensity 0: exactly no light).
MAX_LIGHTS = 2

# Corner c (2 i + j) of a cell lies at module offset (row - a) + (col - b) from the slot's
# pipeline; these are the offsets each corner can take (clamped corners included).
_POSSIBLE = {-2: (0,), -1: (0, 1, 2), 0: (0, 1, 2, 3), 1: (1, 2, 3), 2: (3,)}


def modulo(value, modulus: int, bound: int):
    """``value mod modulus`` of an unsigned ``value < bound`` by repeated subtraction."""
    out = value
    for k in reversed(range(1, -(-bound // modulus))):
        out = Mux(out >= k * modulus, out - k * modulus, out)
    return out


def delayed(m: Module, value, clocks: int, name: str):
    """``value`` ``clocks`` clocks later (plain registers; the pipeline never stalls)."""
    out = value
    for d in range(clocks):
        reg = Signal(len(out), name=f"{name}_d{d}")
        m.d.sync += reg.eq(out)
        out = reg
    return out


def delay_line(m: Module, value, length: int, name: str) -> list:
    """``[value, value 1 clock ago, ..., value length clocks ago]``."""
    taps = [value]
    for d in range(length):
        reg = Signal(len(taps[-1]), name=f"{name}_h{d + 1}")
        m.d.sync += reg.eq(taps[-1])
        taps.append(reg)
    return taps


def _crop_keep(top, consts, ca, cb):
    """The crop unit: whether the sample of cell ``(ca, cb)`` is composited (the crop
    box's three slabs from the slice's constants, comparators only; everything when the
    box is off)."""
    in_a = (consts.crop_a_lo <= ca) & (ca <= consts.crop_a_hi)
    in_b = (consts.crop_b_lo <= cb) & (cb <= consts.crop_b_hi)
    count = consts.crop_k + in_a + in_b
    return ~top.crop | ((count >= top.crop_needed) ^ top.crop_invert)


class PipelineFrontEnd:
    """What pipeline ``k``'s front end hands to the back ends: its evaluated cell
    (``record``: samples, edge lerps, slot flags, ray) and its sample history."""

    def __init__(self, record: dict, history: list):
        self.record, self.history = record, history


def front_end(m: Module, top, k: int, ev: dict, bufs: list, rays) -> PipelineFrontEnd:
    """Address, buffer and interpolation stages of pipeline ``k`` for the evaluated slot
    ``ev`` (``a``, ``g``, ``amod``, ``valid``, ``period``, ``consts``)."""
    dp, geo = top.dp, top.geo
    P, ab = geo.pipelines, geo.axis_bits
    consts = ev["consts"]

    # ---------------------------------------------------------- E0: address stage
    r = modulo(k + 2 * P - consts.qm - ev["amod"], P, 3 * P)
    rr = Signal(range(P), name=f"ev_r{k}")
    b = Signal(ab + 1, name=f"ev_b{k}")
    m.d.comb += [rr.eq(r), b.eq(ev["g"] * P + rr)]
    a = ev["a"]
    ca = Signal(signed(ab + 2), name=f"ca{k}")
    cb = Signal(signed(ab + 2), name=f"cb{k}")
    m.d.comb += [ca.eq(a - consts.da), cb.eq(b - consts.db)]
    r0 = Mux(ca < 0, 0, ca)
    r1 = Mux(ca + 1 > top.n_a - 1, top.n_a - 1, ca + 1)
    c0 = Mux(cb < 0, 0, cb)
    c1 = Mux(cb + 1 > top.n_b - 1, top.n_b - 1, cb + 1)
    u = Signal(signed(geo.offset_bits + 2), name=f"u{k}")
    v = Signal(signed(geo.offset_bits + 2), name=f"v{k}")
    m.d.comb += [u.eq(ca - consts.ia), v.eq(cb - consts.ib)]
    slot_valid = ev["valid"] & (b < top.n_b)
    inside = slot_valid & (u >= 0) & (u < top.height) & (v >= 0) & (v < top.width)
    corners = []
    for idx, (row, col) in enumerate(((r0, c0), (r0, c1), (r1, c0), (r1, c1))):
        addr = Signal(range(geo.t_max), name=f"corner_addr{k}_{idx}")
        off = Signal(signed(4), name=f"corner_off{k}_{idx}")
        m.d.sync += [
            addr.eq(row[:ab] * top.c + divide_by_constant(col[:ab], P, ab)),
            off.eq((row - a) + (col - b)),
        ]
        corners.append((idx, addr, off))
    # The three slices' banks: q in bank p - 1, the next slice in processing order (being
    # filled) in p, the previous in p - 2; the first and last steps use their own slice
    # for the missing neighbour.  A voxel's module moves by +-1 from one slice to the next
    # (the skew (x + y + z) mod P), so the neighbouring slices' corners are one pipeline
    # further along the ring: by -dir before, +dir after (dir = +1 in increasing order).
    p, j = ev["period"], ev["period"] - 1
    banks = Signal(6, name=f"banks{k}")
    cur = (p - 1)[:2]
    first, final = j == 0, j == top.n_kp - 1
    m.d.sync += banks.eq(Cat(Mux(first, cur, (p - 2)[:2]), cur, Mux(final, cur, p[:2])))
    step = Mux(top.forward, 1, -1)
    shifts = Signal(6, name=f"module_shifts{k}")  # three signed(2): before, at, after
    m.d.sync += shifts.eq(Cat(Mux(first, 0, -step)[:2], Const(0, 2), Mux(final, 0, step)[:2]))
    flags = Cat(
        a == 0,
        a == top.n_a - 1,
        b == 0,
        b == top.n_b - 1,
        rr == P - 1,  # the next voxel of the beam is in the next clock group
        rr == 0,  # the previous one in the previous group
        _crop_keep(top, consts, ca, cb),
    )
    side1 = Signal(geo.ray_bits + 2 + (ab + 1) + len(flags), name=f"side1_{k}")
    ray = u[: geo.ray_bits] * top.width + v[: geo.ray_bits]
    m.d.sync += side1.eq(Cat(ray[: geo.ray_bits], inside, slot_valid, j[: ab + 1], flags))
    wts = Signal(2 * dp.interp.weight.width, name=f"weights1_{k}")
    m.d.sync += wts.eq(Cat(consts.wa, consts.wb))

    # The address stage's remaining clocks (ADDRESS_LATENCY - 1 of them).
    extra = ADDRESS_LATENCY - 1
    corners = [
        (idx, delayed(m, addr, extra, f"{addr.name}_a"), delayed(m, off, extra, f"{off.name}_a"))
        for idx, addr, off in corners
    ]
    banks, shifts, side1, wts = (
        delayed(m, v, extra, f"{v.name}_a") for v in (banks, shifts, side1, wts)
    )

    # ---------------------------------------------------------- E1 -> E2: buffer stage
    banks2 = Signal(6, name=f"banks2_{k}")
    shifts2 = Signal(6, name=f"module_shifts2_{k}")
    m.d.sync += [banks2.eq(banks), shifts2.eq(shifts)]
    roles = [banks2[2 * s : 2 * s + 2] for s in range(3)]
    values = [
        [Signal(dp.voxel_bits, name=f"corner{k}_{s}_{idx}") for idx in range(4)] for s in range(3)
    ]
    for idx, addr, off in corners:
        off2 = Signal(signed(4), name=f"corner_off2_{k}_{idx}")
        m.d.sync += off2.eq(off)
        offsets = sorted(
            {o + d for o, users in _POSSIBLE.items() if idx in users for d in (-1, 0, 1)}
        )
        ports = {}  # one read per module and bank, at the corner's in-bank address
        for module in sorted({(k + o) % P for o in offsets}):
            reads = []
            for mem, wr in bufs[module]:
                port = mem.read_port(transparent_for=(wr,))
                m.d.comb += [port.addr.eq(addr), port.en.eq(1)]
                reads.append(port.data)
            ports[module] = Array(reads)
        for s in range(3):
            select = Signal(signed(4), name=f"corner_module{k}_{s}_{idx}")
            m.d.comb += select.eq(off2 + shifts2[2 * s : 2 * s + 2].as_signed())
            with m.Switch(select):
                for o in offsets:
                    with m.Case(o):
                        m.d.comb += values[s][idx].eq(ports[(k + o) % P][roles[s]])
    ray_rd = rays.read_port()
    m.d.comb += [ray_rd.addr.eq(side1[: geo.ray_bits]), ray_rd.en.eq(1)]
    side2 = Signal(len(side1), name=f"side2_{k}")
    wts2 = Signal(len(wts), name=f"weights2_{k}")
    m.d.sync += [side2.eq(side1), wts2.eq(wts)]
    ray2 = side2[: geo.ray_bits]
    live2 = side2[geo.ray_bits]
    valid2 = side2[geo.ray_bits + 1]
    j2 = side2[geo.ray_bits + 2 : geo.ray_bits + 3 + ab]
    flags2 = side2[geo.ray_bits + 3 + ab :]
    span = data.View(ray_layout(geo), ray_rd.data)
    takes = live2 & (span.j_lo <= j2) & (j2 <= span.j_hi)
    last = j2 == span.j_hi

    interp = SliceInterp(dp.interp, dp.voxel_bits)
    m.submodules[f"interp_{k}"] = interp
    w = dp.interp.weight.width
    ip = interp.i.payload
    m.d.comb += [
        interp.i.valid.eq(valid2),
        ip.wa.eq(wts2[:w]),
        ip.wb.eq(wts2[w:]),
        interp.o.ready.eq(1),
    ]
    for s in range(3):
        for idx in range(4):
            m.d.comb += ip.corners[4 * s + idx].eq(values[s][idx])
    # Beside the interpolator (its LATENCY): ray, takes, last, the slot's flags.
    side6 = delayed(m, Cat(ray2, takes, last, flags2), SLICE_LATENCY, f"side{k}")
    out = interp.o.payload
    record = {
        "valid": interp.o.valid,
        "samples": [out.sample[s] for s in range(3)],
        "row": [out.row[0], out.row[1]],
        "col": [out.col[0], out.col[1]],
        "ray": side6[: geo.ray_bits],
        "takes": side6[geo.ray_bits],
        "last": side6[geo.ray_bits + 1],
        "flags": side6[geo.ray_bits + 2 :],
    }
    history = delay_line(m, out.sample[1], 2 * geo.c_max + 1, f"sample_fifo{k}")
    return PipelineFrontEnd(record, history)


def _shader_inputs(m: Module, top, shade: Shade, loading) -> None:
    """The shader's tables and registers: with reflectance maps (VolumePro 500) the two
    maps the host computed (``LOAD_DIFFUSE_MAP`` table 0, ``LOAD_SPEC`` table 1); with
    per-sample Phong its specular table (``LOAD_SPEC``), coefficients and ``MAX_LIGHTS``
    lights."""
    load = top.load.payload
    if shade.cfg.method == "reflectance-map":
        m.d.comb += [
            shade.load.valid.eq(loading(LOAD_SPEC) | loading(LOAD_DIFFUSE_MAP)),
            shade.load.payload.table.eq(load.target == LOAD_SPEC),
        ]
        return
    m.d.comb += [
        shade.load.valid.eq(loading(LOAD_SPEC)),
        shade.load.payload.table.eq(0),
        shade.kd.eq(top.kd),
        shade.ks.eq(top.ks),
    ]
    f = top.dp.shade.normal_frac_bits
    vec = 3 * (f + 2)
    for light in range(MAX_LIGHTS):
        m.d.comb += shade.intensity[light].eq(
            top.intensity[light * COEF_BITS : (light + 1) * COEF_BITS]
        )
        for axis in range(3):
            lo = light * vec + axis * (f + 2)
            m.d.comb += [
                shade.light[light][axis].eq(top.light[lo : lo + f + 2]),
                shade.half[light][axis].eq(top.half[lo : lo + f + 2]),
            ]


def back_end(m: Module, top, k: int, fronts: list, ray_buffer, buffer_lay, loading, enable) -> dict:
    """Gradient, classification, shading and compositing of pipeline ``k``; returns its
    pixel-FIFO push (``push``: a ray's last sample has just been written back; ``ray``),
    whether a sample was composited (``counted``) and its write-back (``write``: address,
    data, enable), for the top to put on a write port of ``ray_buffer``.

    ``ray_buffer`` lives outside the frozen core (the pixel bus reads it while the core
    is frozen), so the read port here is gated by ``enable`` explicitly; the write-back
    is not (a frozen compositor writes the same value again)."""
    dp, geo = top.dp, top.geo
    P = geo.pipelines

    sample_bits = dp.voxel_bits + dp.interp.sample_frac_bits
    own_front = fronts[k].record
    # The sample waits C clocks (one beam) for its next-beam neighbour.
    fields = [
        own_front["takes"],
        own_front["last"],
        own_front["ray"],
        own_front["flags"],
        *own_front["samples"],
        *own_front["row"],
        *own_front["col"],
    ]
    packed = Cat(*fields)
    line = delay_line(m, packed, geo.c_max, f"beam_wait{k}")
    own = Signal(len(packed), name=f"own{k}")
    m.d.comb += own.eq(Array(line)[top.c])
    pos = 0
    parts = []
    for f in fields:
        parts.append(own[pos : pos + len(f)])
        pos += len(f)
    takes, last, ray, flags = parts[:4]
    s_prev, s_cur, s_next, row0, row1, col0, col1 = parts[4:]
    first_a, last_a, first_b, last_b, wrap_up, wrap_dn, keep = (flags[i] for i in range(7))
    up_hist = Array(fronts[(k + 1) % P].history)
    dn_hist = Array(fronts[(k - 1) % P].history)
    c = top.c
    depth = range(len(fronts[k].history))
    back_beam, next_in_beam, prev_in_beam = (
        Signal(depth, name=f"{n}{k}") for n in ("tap_a", "tap_b_up", "tap_b_dn")
    )
    m.d.comb += [
        back_beam.eq(c << 1),
        next_in_beam.eq(Mux(wrap_up, c - 1, c)),
        prev_in_beam.eq(Mux(wrap_dn, c + 1, c)),
    ]
    up_a = Mux(last_a, row1, up_hist[0])
    dn_a = Mux(first_a, row0, dn_hist[back_beam])
    up_b = Mux(last_b, col1, up_hist[next_in_beam])
    dn_b = Mux(first_b, col0, dn_hist[prev_in_beam])
    ahead_p = Mux(top.forward, s_next, s_prev)
    behind_p = Mux(top.forward, s_prev, s_next)
    kp = top.kp
    # Axis order (x, y, z): the principal axis is 2 - kp, a and b the other two in order.
    per_axis = [
        (Mux(kp == 2, ahead_p, up_b), Mux(kp == 2, behind_p, dn_b)),
        (
            Mux(kp == 0, up_a, Mux(kp == 1, ahead_p, up_b)),
            Mux(kp == 0, dn_a, Mux(kp == 1, behind_p, dn_b)),
        ),
        (Mux(kp == 0, ahead_p, up_a), Mux(kp == 0, behind_p, dn_a)),
    ]

    gradient = Gradient(dp.gradient, sample_bits)
    classify = Classify(dp.classify, dp.voxel_bits, dp.interp.sample_frac_bits)
    shade = Shade(dp.shade, MAX_LIGHTS)
    composite = Composite(dp.composite, sample_bits)
    m.submodules[f"gradient_{k}"] = gradient
    m.submodules[f"classify_{k}"] = classify
    m.submodules[f"shade_{k}"] = shade
    m.submodules[f"composite_{k}"] = composite
    load = top.load.payload
    gp = gradient.i.payload
    m.d.comb += gradient.i.valid.eq(takes)
    for axis, (ahead, behind) in enumerate(per_axis):
        m.d.comb += [
            gp.ahead[axis].eq(ahead),
            gp.behind[axis].eq(behind),
            gradient.ratio[axis].eq(
                top.ratio[axis * (RATIO_BITS + 1) : (axis + 1) * (RATIO_BITS + 1)]
            ),
        ]
    m.d.comb += [
        classify.load.valid.eq(loading(LOAD_LUT) | loading(LOAD_GM)),
        classify.load.payload.table.eq(load.target == LOAD_GM),
        classify.load.payload.addr.eq(load.addr),
        classify.load.payload.data.eq(load.data),
        classify.gm_scale.eq(top.gm_scale),
        classify.modulate.eq(top.modulate),
        shade.load.payload.addr.eq(load.addr),
        shade.load.payload.data.eq(load.data),
        shade.ka.eq(top.ka),
        composite.load.valid.eq(loading(LOAD_CORRECTION)),
        composite.load.payload.addr.eq(load.addr),
        composite.load.payload.data.eq(load.data),
        composite.ert_threshold.eq(top.ert_threshold),
        composite.ert_enable.eq(top.ert_enable),
        gradient.o.ready.eq(1),
        classify.o.ready.eq(1),
        shade.o.ready.eq(1),
        composite.o.ready.eq(1),
    ]
    _shader_inputs(m, top, shade, loading)
    # gradient -> classify: the sample beside the gradient unit.
    m.d.comb += [
        classify.i.valid.eq(gradient.o.valid),
        classify.i.payload.sample.eq(delayed(m, s_cur, GRADIENT_LATENCY, f"sample_g{k}")),
        classify.i.payload.magnitude.eq(gradient.o.payload.magnitude),
    ]
    # classify -> shade: the normal beside the classifier.
    normal = delayed(m, gradient.o.payload.normal.as_value(), CLASSIFY_LATENCY, f"normal{k}")
    m.d.comb += [
        shade.i.valid.eq(classify.o.valid),
        shade.i.payload.rgb.eq(classify.o.payload.rgb),
        shade.i.payload.normal.eq(normal),
    ]
    # shade -> composite: unlit scenes take the classifier's colour (the same clocks).
    unshaded = delayed(m, classify.o.payload.rgb.as_value(), SHADE_LATENCY, f"rgb{k}")
    alpha = delayed(m, classify.o.payload.alpha, SHADE_LATENCY, f"alpha{k}")
    units = GRADIENT_LATENCY + CLASSIFY_LATENCY + SHADE_LATENCY
    sample = delayed(m, s_cur, units, f"sample_c{k}")
    side = Cat(ray, last, keep)
    # The compositing buffer is read one clock before the sample reaches the compositor.
    side8 = delayed(m, side, units - 1, f"side_c{k}")
    buf_rd = ray_buffer.read_port()
    m.d.comb += [buf_rd.addr.eq(side8[: geo.ray_bits]), buf_rd.en.eq(enable)]
    side9 = delayed(m, side8, 1, f"side9_{k}")
    entry = data.View(buffer_lay, buf_rd.data)
    cp = composite.i.payload
    m.d.comb += [
        composite.i.valid.eq(shade.o.valid),
        cp.acc.eq(entry.acc),
        cp.rgb.eq(Mux(top.lit, shade.o.payload.rgb.as_value(), unshaded)),
        cp.alpha.eq(alpha),
        cp.mip.eq(entry.mip),
        cp.sample.eq(sample),
    ]
    # Writeback: the compositor's answer, for rays still alive.
    after = delayed(m, Cat(side9, entry.alive), COMPOSITE_LATENCY, f"sidew{k}")
    ray_w = after[: geo.ray_bits]
    last_w = after[geo.ray_bits]
    keep_w = after[geo.ray_bits + 1]  # a cropped sample is not written back
    alive_w = after[len(side)]
    out = composite.o.payload
    counted = composite.o.valid & keep_w & (alive_w | top.mip)
    wb_data = Signal(buffer_lay.size, name=f"writeback_data{k}")
    m.d.comb += wb_data.eq(Cat(out.acc, out.mip, ~out.terminated))
    return {
        "push": composite.o.valid & last_w,
        "ray": ray_w,
        "counted": counted,
        # Not gated: a frozen compositor repeats the same write, and the pixel bus may
        # read the ray as soon as the FIFO took it, in the clock of its write.
        "write": (ray_w, wb_data, counted),
    }
