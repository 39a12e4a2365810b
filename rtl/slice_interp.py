"""Slice interpolator of the Cube-4 top: one cell's bilinear sample on three slices and
the edge lerps the gradient's boundary neighbours need; bit-exact with
``models.units.interp.bilinear`` / ``lerp``.

# Ref: architectures.md section 1.3 items 4-5 (samples interpolated between the voxels of a
#      slice; gradients from the samples of slices k-1, k, k+1); models/units/interp.py.

The Cube-4 samples lie on voxel slices (principal weight 0), so a sample is
``lerp(lerp(c00, c01, wb), lerp(c10, c11, wb), wa)`` of its cell's corners ``c<i><j>`` =
voxel ``(a0 + i, b0 + j)`` promoted by ``S`` fraction bits (the model's ``bilinear``: the
interpolator's x, y, z lerp order with a zero principal weight).  Per cell this unit gives

* ``sample[3]``: that sample on the slices before, at and after the current one, at the
  current slice's weights (the gradient's principal-axis neighbours are the samples at
  the same in-slice position on slices ``q - 1`` and ``q + 1``);
* ``row[2]``: the current slice's two ``b`` lerps (rows ``a0`` and ``a0 + 1``) and
  ``col[2]``: the two ``a`` lerps ``lerp(c00, c10, wa)``, ``lerp(c01, c11, wa)`` (columns
  ``b0`` and ``b0 + 1``).  A cell beyond the volume's edge has both corners of one axis
  clamped to the edge voxel, so its sample is exactly one of these lerps: they are the
  gradient neighbours no other slot evaluates (``lerp(x, x, w) = x`` exactly).

Stages (``LATENCY`` = the trilinear interpolator's, ``II = 1``): input register
(promote), the ``b`` lerps and the column lerps (product, sum), the ``a`` lerps (product,
sum), then registers to the interpolator's depth.
"""

from __future__ import annotations

from amaranth import Module, unsigned
from amaranth.lib import data, wiring

from models.units.interp import InterpConfig
from rtl import interp
from rtl.common import StallingPipeline, unit_ports
from rtl.interp import lerp_stages, sample_shape

__all__ = ["SliceInterp", "LATENCY", "II", "input_layout", "output_layout"]

#: The stage plan: the trilinear interpolator's depth (the Cube-4 rungs time the slice
#: interpolator as ``models.units.interp.LATENCY``).
STAGES = ("promote", "b_product", "b_sum", "a_product", "a_sum")
LATENCY = interp.LATENCY
II = 1


def input_layout(cfg: InterpConfig, voxel_bits: int):
    """``corners[12]``: corner ``4 s + 2 i + j`` is ``c<i><j>`` of slice ``s`` (0 before,
    1 current, 2 after), unsigned ``B`` bits; ``wa``, ``wb`` (raw UQ1.W)."""
    w = unsigned(cfg.weight.width)
    return data.StructLayout(
        {
            "corners": data.ArrayLayout(unsigned(voxel_bits), 12),
            "wa": w,
            "wb": w,
        }
    )


def output_layout(cfg: InterpConfig, voxel_bits: int):
    """``sample[3]``, ``row[2]``, ``col[2]``: ``B + S`` bits each."""
    s = unsigned(voxel_bits + cfg.sample_frac_bits)
    return data.StructLayout(
        {
            "sample": data.ArrayLayout(s, 3),
            "row": data.ArrayLayout(s, 2),
            "col": data.ArrayLayout(s, 2),
        }
    )


class SliceInterp(wiring.Component):
    """Bilinear samples of one cell on three slices, and the current slice's edge lerps;
    ``cfg`` and ``voxel_bits`` (``B``) as :class:`rtl.interp.Interp`'s."""

    def __init__(self, cfg: InterpConfig | None = None, voxel_bits: int = 12):
        cfg = cfg if cfg is not None else InterpConfig()
        self.cfg, self.voxel_bits = cfg, voxel_bits
        super().__init__(unit_ports(input_layout(cfg, voxel_bits), output_layout(cfg, voxel_bits)))

    def elaborate(self, platform):
        m = Module()
        cfg, s = self.cfg, self.cfg.sample_frac_bits
        pipe = StallingPipeline(m, self.i, self.o, LATENCY)
        wide, payload = sample_shape(cfg, self.voxel_bits), self.i.payload

        v = [
            [
                pipe.register(payload.corners[4 * k + c] << s, name=f"v{k}_{c}", shape=wide)
                for c in range(4)
            ]
            for k in range(3)
        ]
        wa1 = pipe.register(payload.wa, name="wa1")
        wb1 = pipe.register(payload.wb, name="wb1")
        rows = [
            lerp_stages(pipe, [(v[k][0], v[k][1]), (v[k][2], v[k][3])], wb1, cfg, wide, f"r{k}_")
            for k in range(3)
        ]
        cols = lerp_stages(pipe, [(v[1][0], v[1][2]), (v[1][1], v[1][3])], wa1, cfg, wide, "c")
        wa2 = pipe.delay(wa1, 2, name="wa2")
        samples = lerp_stages(
            pipe, [(rows[k][0], rows[k][1]) for k in range(3)], wa2, cfg, wide, "s"
        )
        pad = LATENCY - len(STAGES)
        rows3 = [pipe.delay(rows[1][i], 2 + pad, name=f"row3_{i}") for i in range(2)]
        cols3 = [pipe.delay(cols[j], 2 + pad, name=f"col3_{j}") for j in range(2)]
        out = self.o.payload
        for k in range(3):
            m.d.comb += out.sample[k].eq(pipe.delay(samples[k], pad, name=f"sample{k}"))
        for i in range(2):
            m.d.comb += [out.row[i].eq(rows3[i]), out.col[i].eq(cols3[i])]
        return m
