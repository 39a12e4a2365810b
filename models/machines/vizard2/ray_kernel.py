"""VIZARD II's ray loop compiled: a frame's packets, round by round, through cache, SDRAM
and datapath, and out through the pixel FIFO.

# Ref: architectures.md section 5 (VIZARD II); models/machines/vizard2/cycle.py (the unit
#      chain this loop is checked against, and its timing rules 1-6); models/fused_stage.py
#      (the shading and blending shared with every compiled kernel).

:class:`~models.machines.vizard2.cycle.VizardMachine` marches a packet of rays in lock
step, one round (one step of each live ray) at a time.  Its reference form runs each
round as a chain of NumPy calls on arrays of a few dozen samples: positions, the block
cache's lookups (resolved at once, sorted by line), the fills' SDRAM bursts, the issue
timing and the back end's units; at 64^3 that is 1569 rounds and some hundred calls each.
Here one compiled call runs the frame's packets in the ray generator's order (one call a
packet when a progress report is asked for or the pixel FIFO has depth 0), each round's
samples in issue order, first through the memory side
(:func:`~models.machines.vizard2.ray_memory.gather_round`, one call a round), then the
datapath:

- the position (the plan's own float expression, ``SamplePlan.position``), the cell and
  weights (:func:`~models.units.interp.cell_weight`);
- the cache lookups (:mod:`models.machines.vizard2.ray_memory`) of the distinct blocks
  of the cell's 8 voxels, corner order (the reference's ``BlockCache.fetch`` order),
  each a hit or a fill of its direct-mapped line from the memory image (the faults
  ``corrupt_line`` and ``dropped_fill`` applied as the fill writes); the sample's corners
  are read from the lines at once (its up to 8 blocks sit in different lines) into the
  round's corner rows: what the reference's line-store rows hold for it;
- for a live ray, the datapath: trilinear value, LUT, interpolated gradient-table entries,
  modulation, then per round :func:`~models.fused_stage.shade_and_blend` (composite) or
  the maximum (MIP);
- per round, the fills' bursts per lookup group sorted page by page and scheduled by the
  SDRAM controller's own compiled loop (:func:`hwsim.memory.sdram_kernel.schedule_requests`,
  on the controller's state), the stalls, issue cycles, early-termination feedback and the
  stage counters (summed: the stages' accounting is linear in its blocks);
- per packet, its retirement (rule 5): the accumulators to the pixel bus and the pixels
  through the pixel FIFO (:func:`~models.machines.vizard2.ray_memory.retire_packet`,
  ``hwsim.engine.DrainFifo``'s rules on its state), a full FIFO stalling the issue.

Helpers called per sample take scalars only: an array handed to a helper numba inlines
costs two atomic reference-count updates a call, which were a fifth of the loop's time
when the lookups and the corner reads were per-sample helpers (issue 36, round 3).

**Scope** (:meth:`RayKernel.for_machine`): composite within
:func:`models.fused_stage.eligible` (so a lit perspective frame, a shader per ray, is out),
no crop or cut planes, and MIP; no VCD trace.  Anything else, and ``compiled=False``,
takes the unit chain.  ``tests/models/test_cycle_vizard2_kernel.py`` checks both give the
same image, cycles and counters on every fault and feature.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

import numba
import numpy as np

from hwsim.numerics import ROUNDING_CODES
from models.datapath import Datapath
from models.fused_stage import (
    _BTF_UP,
    GRAD_FLAGS,
    STAGE_HASH,
    StageConstants,
    eligible,
    shade_and_blend,
    world_and_modulate,
)
from models.machines.vizard2 import ray_memory
from models.machines.vizard2.config import FEEDBACK, FILL_WRITE
from models.machines.vizard2.ray_memory import (
    _CLOCK,
    _CYCLES,
    _FIFO_STALLS,
    _FILLS,
    _HITS,
    _ISSUED,
    _LOOKUPS,
    _RETIRED,
    _SAMPLES,
    _SD_N,
    _SPEC,
    _STALLS,
    FIFO,
    REGS,
    fills_timed,
    gather_round,
    issue_round,
    retire_packet,
)
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import interp as interp_unit

__all__ = ["LOOP_HASH", "RayKernel"]

#: Part of the kernel's cache key: numba keys a cached kernel by its own file, not by the
#: functions it inlines or calls (the shared stage, the memory side).
LOOP_HASH = hashlib.sha256(
    (STAGE_HASH + Path(ray_memory.__file__).read_text(encoding="utf-8")).encode()
).hexdigest()


@numba.njit(inline="always")
def _trilinear(v0, v1, v2, v3, v4, v5, v6, v7, wz, wy, wx, s_bits, w_bits, w_code):
    """``interp.interpolate`` of one sample's 8 raw corners ``v<c>`` (``c = 4 dz + 2 dy +
    dx``): promoted, then lerps along x (four), y (two), z (``interp.lerp_corners``).
    Scalars only: an array handed to an inlined helper costs a reference count a call."""
    lerp = interp_unit.lerp_raw
    a0 = lerp(np.int64(v0) << s_bits, np.int64(v1) << s_bits, wx, w_bits, w_code)
    a1 = lerp(np.int64(v2) << s_bits, np.int64(v3) << s_bits, wx, w_bits, w_code)
    a2 = lerp(np.int64(v4) << s_bits, np.int64(v5) << s_bits, wx, w_bits, w_code)
    a3 = lerp(np.int64(v6) << s_bits, np.int64(v7) << s_bits, wx, w_bits, w_code)
    b0 = lerp(a0, a1, wy, w_bits, w_code)
    b1 = lerp(a2, a3, wy, w_bits, w_code)
    return np.int64(lerp(b0, b1, wz, w_bits, w_code))


@numba.njit(inline="always")
def _live_rays(packet, j, j_lo, j_hi, ert_on, alive, ray_ids, clock, terminated_at, feedback,
               live):  # fmt: skip
    """The packet's rays that issue step ``j`` into ``live`` (their count): those whose
    range holds it, less (rule 3) those whose termination is known at ``clock``."""
    n = 0
    for q in range(packet.shape[0]):
        r = packet[q]
        if j_lo[r] <= j <= j_hi[r]:
            if ert_on and not alive[ray_ids[r]] and clock >= terminated_at[r] + feedback:
                continue
            live[n] = r
            n += 1
    return n


@numba.njit(inline="always")
def _visible_samples(n, live, ray_ids, before, w, v, mip, values, grads, world, modulates,
                     touched, acc, rgba, g, vis_rays, regs, rgb12, alpha12, w_ratio, gm_scale,
                     gm_entries, gm_table, s_bits, w_bits, w_code, lut_shift, entries):  # fmt: skip
    """The datapath of a round's ``n`` samples (weights ``w``, corners ``v`` as
    :func:`~models.machines.vizard2.ray_memory.gather_round` left them): for each live
    ray's sample (or every one, MIP) the trilinear value; MIP keeps the maximum, composite
    classifies and keeps the visible ones (``rgba``, ``g``, ``vis_rays``: colours,
    gradients interpolated from the table, modulated) for the round's blend.  Returns the
    visible count.  Called once a round: an array handed over is reference counted."""
    m = 0
    for i in range(n):
        if not (mip or before[i]):
            continue  # a dead ray's sample: fetched, not processed
        regs[_SAMPLES] += 1
        if not values:
            continue  # timing only, no ray ends early: no clock waits on a value
        ray = ray_ids[live[i]]
        touched[ray] = True
        wz, wy, wx = w[i, 0], w[i, 1], w[i, 2]
        value = _trilinear(v[i, 0], v[i, 1], v[i, 2], v[i, 3], v[i, 4], v[i, 5], v[i, 6],
                           v[i, 7], wz, wy, wx, s_bits, w_bits, w_code)  # fmt: skip
        if mip:
            acc[ray, 0] = max(acc[ray, 0], value)
            continue
        idx = classify_unit.lut_index_raw(value, lut_shift, entries)
        alpha = alpha12[idx]
        if alpha <= 0:
            continue  # transparent: changes nothing (Backend._composite's `vis`)
        gx = gy = gz = np.int64(0)
        if grads:
            gx = _trilinear(v[i, 8], v[i, 9], v[i, 10], v[i, 11], v[i, 12], v[i, 13], v[i, 14],
                            v[i, 15], wz, wy, wx, s_bits, w_bits, w_code)  # fmt: skip
            gy = _trilinear(v[i, 16], v[i, 17], v[i, 18], v[i, 19], v[i, 20], v[i, 21],
                            v[i, 22], v[i, 23], wz, wy, wx, s_bits, w_bits, w_code)  # fmt: skip
            gz = _trilinear(v[i, 24], v[i, 25], v[i, 26], v[i, 27], v[i, 28], v[i, 29],
                            v[i, 30], v[i, 31], wz, wy, wx, s_bits, w_bits, w_code)  # fmt: skip
            if world or modulates:  # a call hands two arrays over: counted
                gx, gy, gz, alpha = world_and_modulate(
                    gx, gy, gz, alpha, world, modulates, w_ratio, gm_scale, gm_entries,
                    gm_table,
                )  # fmt: skip
        g[0, m], g[1, m], g[2, m] = gx, gy, gz
        rgba[0, m], rgba[1, m], rgba[2, m] = rgb12[idx, 0], rgb12[idx, 1], rgb12[idx, 2]
        rgba[3, m], vis_rays[m] = alpha, ray
        m += 1
    return m


@numba.njit(inline="always")
def _blend_opacity(rgba, vis_rays, m, grad_p, table, acc, ert_thr, alive, one, acc_code):
    """The opacity channel of :func:`~models.fused_stage.shade_and_blend`'s blend and its
    termination (timing only): a ray's accumulated opacity reads only its own samples'
    opacities, never their colours or shading, so it ends the ray where the full blend
    does.  Saturations are not counted."""
    btf_up = grad_p[_BTF_UP]
    for j in range(m):
        alpha = table[min(max(rgba[3, j], 0), 4096)]
        ray = vis_rays[j]
        if btf_up >= 0:
            a_new = composite_unit.btf_raw(acc[ray, 3], 4096, alpha, btf_up, acc_code)
        else:
            a_new = acc[ray, 3] + composite_unit.ftb_weight_raw(acc[ray, 3], alpha, one, acc_code)
        acc[ray, 3] = min(max(a_new, 0), one)
        if ert_thr >= 0:
            alive[ray] = acc[ray, 3] < ert_thr


def _make_kernel(stage_hash: str, constants: tuple[int, ...] | None):
    """The packet kernel, compiled for one configuration of formats (``constants``: the
    ``config`` tuple, taken from the closure as compile-time constants, as
    :func:`models.fused._make_kernel` does for a machine's own formats) or for any
    (None: read from the ``config`` argument)."""
    specialised = constants is not None
    fixed = constants if constants is not None else (0,) * 9

    def kernel(
        flat, starts, k0, k1, fifo, bus_acc, bus_touched, ray_ids, j_lo, j_hi, orig, dirs,
        k_first, k_dir, dt, shape, nb, sets, tag, cvals, cgx, cgy, cgz, ivals, igx, igy, igz,
        faults, lay, ratio, sd_out, sd_arr,
        sd_params, sd_regs, sd_banks, sd_booked, sd_log, terminated_at, alive, touched, acc,
        flags, busy, regs, rgb12, alpha12, grad_p, w_ratio, gm_table, light, half, intensity,
        spec, maps, table, ert_thr, sat, config,
    ):  # fmt: skip
        if len(stage_hash) == 0:  # never: keeps the hash in the cache key
            return sd_out, sd_arr, sd_booked, sd_log
        s_bits, w_bits, w_code, lut_shift, entries, f_bits, spec_entries, one, acc_code = (
            fixed if specialised else config
        )
        mip, ert_on, grads = flags[0] != 0, flags[1] != 0, flags[4] != 0
        feedback, P = flags[2], flags[3]
        world, modulates = grad_p[GRAD_FLAGS[0]] != 0, grad_p[GRAD_FLAGS[1]] != 0
        # Timing only (flags[5]): the datapath runs only as far as it decides a clock:
        # the opacity that ends a ray (rule 3), its gradient only where it modulates it.
        timing = flags[5] != 0
        values = not timing or ert_on
        grads = grads and (not timing or (ert_on and modulates))
        gm_scale, gm_entries = grad_p[GRAD_FLAGS[2]], grad_p[GRAD_FLAGS[3]]
        n_pk = 1  # the largest packet's rays
        for k in range(k0, k1):
            n_pk = max(n_pk, starts[k + 1] - starts[k])
        # Per round: its live rays, their state before it, issue cycles, the groups'
        # stalls, the misses (sample, block), each sample's weights and corners (8 values,
        # 24 gradient-table entries) and the visible samples' colours and gradients.
        rows = np.empty((3, n_pk), np.int64)
        live, vis_rays, issue = rows[0], rows[1], rows[2]
        before, stall = np.empty(n_pk, np.bool_), np.zeros(n_pk // P + 1, np.int64)
        miss_s, miss_b = np.empty(8 * n_pk, np.int64), np.empty(8 * n_pk, np.int64)
        rgba, g = np.empty((4, n_pk), np.int64), np.empty((3, n_pk), np.int64)
        w, v = np.empty((n_pk, 3), np.int64), np.empty((n_pk, 32), np.int64)
        keys = np.empty((3, 8 * n_pk * (lay[3] + lay[4])), np.int64)  # fills' page keys
        for k in range(k0, k1):  # packets k0 .. k1 - 1, in the ray generator's order
            packet = flat[starts[k] : starts[k + 1]]
            j0, j1 = j_lo[packet].min(), j_hi[packet].max()
            for j in range(j0, j1 + 1):
                clock = regs[_CLOCK]
                n = _live_rays(packet, j, j_lo, j_hi, ert_on, alive, ray_ids, clock, terminated_at,
                               feedback, live)  # fmt: skip
                if n == 0:
                    continue
                n_miss = gather_round(
                    n, live, ray_ids, orig, dirs, (k_first + k_dir * j) * dt, shape, nb, sets, tag,
                    cvals, cgx, cgy, cgz, ivals, igx, igy, igz, grads, values, mip, faults, miss_s,
                    miss_b, regs, alive, before, w, v, w_bits, w_code,
                )  # fmt: skip
                m = _visible_samples(
                    n, live, ray_ids, before, w, v, mip, values, grads, world, modulates,
                    touched, acc, rgba, g, vis_rays, regs, rgb12, alpha12, w_ratio, gm_scale,
                    gm_entries, gm_table, s_bits, w_bits, w_code, lut_shift, entries,
                )  # fmt: skip
                if timing and values:
                    _blend_opacity(rgba, vis_rays, m, grad_p, table, acc, ert_thr, alive, one,
                                   acc_code)  # fmt: skip
                elif not mip:
                    shade_and_blend(
                        rgba, vis_rays, g, m, grad_p, light, half, intensity, spec, maps, table,
                        acc, ert_thr, alive, sat, f_bits, spec_entries, one, acc_code,
                    )  # fmt: skip
                for q in range((n + P - 1) // P):  # a loop, not a slice: no view to count
                    stall[q] = 0
                if n_miss:
                    sd_out, sd_arr, sd_booked, sd_log = fills_timed(
                        miss_s, miss_b, n_miss, clock, stall, P, lay, ratio, sd_out, sd_arr,
                        sd_params, sd_regs, sd_banks, sd_booked, sd_log, regs, keys,
                    )  # fmt: skip
                issue_round(n, P, stall, clock, busy, ert_on, before, alive, ray_ids, live,
                            terminated_at, issue, regs)  # fmt: skip
            if fifo[0] > 0:  # rule 5 here: the packet's pixels leave through the FIFO
                retire_packet(packet, ray_ids, acc, touched, bus_acc, bus_touched, fifo, regs)
        return sd_out, sd_arr, sd_booked, sd_log

    return numba.njit(cache=True, nogil=True)(kernel)


@functools.cache
def _kernel(config: tuple[int, ...] | None):
    """The kernel specialised for ``config`` (None: the generic one), made once per
    process on first use."""
    return _make_kernel(LOOP_HASH, config)


class RayKernel(StageConstants):
    """The compiled ray loop of one VIZARD II frame (None from :meth:`for_machine` when
    the frame is out of its scope, see Scope)."""

    #: Timing only (:meth:`VizardMachine.timing`): the loop skips the datapath where it
    #: decides no clock (flags[5]); the image and the saturation counts are then void.
    timing = False

    @classmethod
    def for_machine(cls, machine) -> RayKernel | None:
        be = machine.be
        if not be.compiled or machine.trace is not None or be.exercise_unused:
            return None
        if be.scene.crop is not None or be.scene.cut_planes or be.depth is not None:
            return None
        if be.mode == "mip":
            return cls(machine, np.zeros(1, dtype=np.int64))
        if not eligible(be):
            return None
        table = StageConstants(be).table(machine.plan._dt)
        return None if table is None else cls(machine, table)

    def __init__(self, machine, table: np.ndarray) -> None:
        be = machine.be
        if be.mode == "mip":
            self._mip_constants(be)
        else:
            super().__init__(be)
        self.m, self.dt_table = machine, table
        mip_own = be.mode == "mip" and be.dp == Datapath.for_volume(be.arch, be.volume)
        own = mip_own or (be.mode != "mip" and self.own_formats)
        self.kernel = _kernel(self.config if own else None)

    def _mip_constants(self, be) -> None:
        """MIP reads only the interpolator's formats: the composite stage's constants
        (which need a LUT) as empty arrays of their types."""
        dp = be.dp
        self.backend = be
        self.config = (
            be.S,
            dp.interp.weight_bits,
            ROUNDING_CODES[dp.interp.rounding],
            0,
            1,
            0,
            0,
            1,
            0,
        )
        self.rgb12 = np.zeros((1, 3), np.int64)
        self.alpha12 = self.ratio = self.gm_table = self.intensity = np.zeros(1, np.int64)
        self.spec = np.zeros(2, np.int64)
        self.grad_p = np.zeros(12, np.int64)
        self.light = self.half = np.zeros((0, 3), np.int64)
        self.maps = np.zeros((2, 1), np.int64)
        self.ert_thr = -1

    def _cache_arrays(self) -> tuple:
        """The line store and the memory image (gradients: dummies when not read)."""
        cache, image = self.m.cache, self.m.image
        if cache.gradients is None:
            none = np.zeros((1, 64), dtype=np.int32)
            return cache.values, none, none, none, image.values, none, none, none
        return cache.values, *cache.gradients, image.values, *image.gradients

    def run_frame(self, packets, state, bus, pixel_fifo, progress) -> tuple[np.ndarray, int, int]:
        """Every packet (``packets``: the generator's order and each packet's start,
        :meth:`VizardMachine._packets`) through the kernel, its pixels then through the
        pixel FIFO (rule 5); returns the stage totals (busy per lane, cycles, stalled
        cycles)."""
        m, be, plan = self.m, self.backend, self.m.plan
        sd, sdc = m.sdram, m.memory_cfg.sdram
        lay = m.image.layout
        layout = np.array(
            [lay.value_words, lay.gradient_words, lay.gradient_base, lay.value_bursts,
             lay.gradient_bursts, lay.burst_length, lay.columns, lay.banks, sdc.rows,
             sdc.cas_latency + sdc.burst_cycles, FILL_WRITE],
            dtype=np.int64,
        )  # fmt: skip
        faults = np.array([-1, 0, -1], dtype=np.int64)
        if m.faults.corrupt_line is not None:
            faults[:2] = m.faults.corrupt_line
        if m.faults.dropped_fill is not None:
            faults[2] = m.faults.dropped_fill
        mip = be.mode == "mip"
        flags = np.array(
            [mip, m.ert, FEEDBACK, m.P, m.cache.gradients is not None, self.timing], dtype=np.int64
        )
        acc = state.acc.reshape(-1, 1) if mip else state.acc
        dirs = np.ascontiguousarray(plan._d, dtype=np.float64).reshape(-1, 3)
        busy = np.zeros(m.P, dtype=np.int64)
        regs = np.zeros(len(REGS), dtype=np.int64)
        sat = np.zeros(2, dtype=np.int64)
        arrays = (sd._out, sd._arrivals, sd._booked, sd._log)  # the controller's state
        store = self._cache_arrays()
        shape = np.asarray(m.image.shape, dtype=np.int64)
        nb, sets = np.asarray(m.image.nb, np.int64), np.asarray(m.cache.sets, np.int64)
        # One call for the frame, the pixel FIFO in the loop; one a packet (the FIFO
        # here) for a progress report or a FIFO of depth 0 (its deadlock is reported
        # by the Python FIFO).
        compiled_fifo = progress is None and pixel_fifo.depth > 0
        fifo = np.array([getattr(pixel_fifo, f) for f in FIFO], dtype=np.int64)
        fifo[0] = fifo[0] if compiled_fifo else 0
        flat, starts = packets
        n_packets = starts.size - 1
        bus_acc = bus.acc.reshape(-1, 1) if mip else bus.acc
        chunks = [(0, n_packets)] if compiled_fifo else [(k, k + 1) for k in range(n_packets)]
        for k0, k1 in chunks:
            arrays = self.kernel(
                flat, starts, k0, k1, fifo, bus_acc, bus.touched, plan.ray_ids, plan.j_lo,
                plan.j_hi, plan._o, dirs, plan.k_first, plan.k_dir, float(plan._dt), shape, nb,
                sets, m.cache.tag, *store, faults, layout, float(sdc.clock_ratio), *arrays[:2],
                sd._params, sd._regs, sd._banks, *arrays[2:], m.terminated_at, state.alive,
                state.touched, acc, flags, busy, regs, self.rgb12, self.alpha12, self.grad_p,
                self.ratio, self.gm_table, self.light, self.half, self.intensity, self.spec,
                self.maps, self.dt_table, self.ert_thr, sat, self.config,
            )  # fmt: skip
            if not compiled_fifo:
                rays = plan.ray_ids[flat[starts[k0] : starts[k1]]]
                self._retire(rays, state, bus, pixel_fifo, regs)
                if progress is not None:
                    progress(k1, n_packets)
        if compiled_fifo:
            for name, value in zip(FIFO[2:], fifo[2:], strict=True):
                setattr(pixel_fifo, name, int(value))
        sd._out, sd._arrivals, sd._booked, sd._log = arrays
        sd._n = int(regs[_SD_N])
        self.count_saturations(sat)
        m.clock.advance(int(regs[_CLOCK]))
        cache = m.cache
        cache.fills, cache.lookups, cache.hits = (int(regs[i]) for i in (_FILLS, _LOOKUPS, _HITS))
        m.issued, m.speculative = int(regs[_ISSUED]), int(regs[_SPEC])
        state.samples += int(regs[_SAMPLES])
        fifo_stall = int(regs[_FIFO_STALLS])
        return busy, int(regs[_CYCLES]) + fifo_stall, int(regs[_STALLS]) + fifo_stall

    @staticmethod
    def _retire(rays, state, bus, pixel_fifo, regs) -> None:
        """Rule 5 in Python (:func:`~models.machines.vizard2.ray_memory.retire_packet`'s
        work, for a FIFO the loop does not hold): the packet's accumulators (pixels
        ``rays``) to the pixel bus, its pixels into the FIFO, the clock past its stall."""
        bus.acc[rays] = state.acc[rays]
        bus.touched[rays] = state.touched[rays]
        retired = int(regs[_RETIRED])
        stall = pixel_fifo.advance(int(regs[_CLOCK]) - retired, int(rays.size), retired)
        regs[_CLOCK] += stall
        regs[_FIFO_STALLS] += stall
        regs[_RETIRED] = regs[_CLOCK]
