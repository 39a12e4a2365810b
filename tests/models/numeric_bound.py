"""A per-pixel bound on |golden - functional|, derived from the datapath's formats.

The functional rung differs from the float64 golden renderer at the same sample positions
only by the fixed-point arithmetic of docs/numerics.md: every format, rounding and
table is known, so the difference a pixel may show is computable from the scene's inputs
and the formats, before either image is looked at.  :func:`pixel_bound` computes it, one
bound per pixel and channel; :func:`agreement` compares two images against it.  The
derivation, with its assumptions, is in docs/numerics.md ("End to end: a bound derived
from the formats").

What the bound is built from (nothing here is fitted to a measured image):

* the sample positions of the plan and the scene's inputs (volume, transfer function,
  lights, material), which both sides share;
* the datapath's formats (:class:`models.datapath.Datapath`: weight and fraction bits,
  LUT size and storage widths, normal, coefficient and table widths, accumulator and
  output widths) and the roundings docs/numerics.md states for each;
* float64 evaluations of the ideal (golden) quantities, written here from the documented
  formulas: no function of ``hwsim.golden`` that computes a sample, a colour or a
  composite is called, so an error in the golden renderer does not move the bound.

Per sample, each stage gives an interval that must hold the functional rung's value (the
quantised position fractions, the interpolated value, the LUT entries it can index, the
normal and dot products, the shaded colour, the corrected opacity); the distance from the
golden value to the far end of that interval is the sample's error.  Along a ray the
sample errors are composited by an exact telescoping identity (golden samples in front
of sample ``j``, functional samples behind it), then the compositor's roundings and the
output rounding are added.  Shear-warp's base-plane warp is bilinear with non-negative
weights, so the base-plane bound warps into the image's.

Covered: composite (front to back and back to front, post-classification, Phong or
reflectance maps, lit or not, any lights, parallel or perspective), MIP, MinIP, X-ray and
iso on trilinear interpolation.  Anything else (pre-classification, gradient-magnitude
modulation, multi-LUT classification, embedded geometry, the cursor, crop and cut planes,
early ray termination) raises ``NotImplementedError`` naming it.

The bound is split by responsibility: this module is the API (:func:`pixel_bound`,
:func:`agreement`, the pairs the tests render); ``numeric_bound_units.py`` holds each
unit's per-sample bound (interpolation, classification and opacity correction,
gradients, shading), ``numeric_bound_rays.py`` the per-ray bounds of each mode
(compositing, MIP and MinIP, X-ray, iso) built on them, and ``numeric_bound_maps.py``
the formats' rounding maps and vector helpers they share.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numeric_bound_rays import Bound

from hwsim.golden import make_plan, render_golden
from hwsim.numerics import psnr
from hwsim.run.fidelity import algorithms, resolve_arch
from hwsim.spec.transfer import resolve_transfer
from models.datapath import Datapath
from models.frame import frame_of
from models.functional import render_functional

__all__ = [
    "Agreement",
    "agreement",
    "golden_at_machine",
    "machine_pair",
    "pixel_bound",
]


# ------------------------------------------------------------------------------ the API


@dataclass(frozen=True)
class Agreement:
    """Golden against functional, judged by the derived bound.

    ``excess`` is ``max(|golden - functional| - bound)`` over pixels and channels: the
    images agree when it is at most 0.  ``ratio`` is ``max(|golden - functional| /
    bound)`` (the share of the bound the worst pixel uses); ``violations`` counts the
    values over the bound; ``psnr`` is reported, not judged.
    """

    excess: float
    ratio: float
    violations: int
    max_error: float
    bound_min: float
    bound_median: float
    psnr: float

    @property
    def ok(self) -> bool:
        return self.excess <= 0.0

    def __str__(self) -> str:
        return (
            f"excess {self.excess:+.5f} ({self.violations} values over the bound), "
            f"worst |g-f|/bound {self.ratio:.3f}, max |g-f| {self.max_error:.5f}, "
            f"bound min {self.bound_min:.5f} median {self.bound_median:.5f}, "
            f"PSNR {self.psnr:.1f} dB"
        )


def agreement(golden: np.ndarray, fixed: np.ndarray, bound: np.ndarray) -> Agreement:
    """Compare two images (same shape) against a :func:`pixel_bound`."""
    golden, fixed = np.asarray(golden, float), np.asarray(fixed, float)
    if golden.shape != fixed.shape or golden.shape != bound.shape:
        raise ValueError(f"shapes differ: {golden.shape}, {fixed.shape}, {bound.shape}")
    err = np.abs(golden - fixed)
    over = err - bound
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bound > 0, err / bound, np.where(err > 0, np.inf, 0.0))
    return Agreement(
        excess=float(over.max()),
        ratio=float(ratio.max()),
        violations=int(np.count_nonzero(over > 0)),
        max_error=float(err.max()),
        bound_min=float(bound.min()),
        bound_median=float(np.median(bound)),
        psnr=float(psnr(golden, fixed)),
    )


def golden_at_machine(scene, volume, arch, transfer=None):
    """Golden at ``arch``'s sample positions *and with its algorithms*, as
    ``hwsim.run.fidelity.render(fidelity="golden", arch=...)`` renders it: the machine's
    gradient source where the scene names none, and its reflectance maps where it shades
    by them (``render_golden(..., reflectance_map=map_size)``); every planned position
    (``leap=False``).  Returns ``(scene as rendered, GoldenResult)``: the functional rung
    must be given the same scene."""
    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    chosen = algorithms(machine)
    if scene.render.gradient is None:
        scene = scene.replace(render=dataclasses.replace(scene.render, gradient=chosen.gradient))
    tf = transfer if transfer is not None else resolve_transfer(scene.transfer, volume)
    maps = chosen.map_size if chosen.shading == "reflectance-map" else None
    result = render_golden(
        scene, volume, tf, sampling=machine.order, leap=False, reflectance_map=maps
    )
    return scene, result


def machine_pair(scene, volume, arch, transfer=None):
    """``(golden, functional, bound)`` of one frame: golden with the machine's algorithms
    (:func:`golden_at_machine`), the functional rung on the same plan, and
    :func:`pixel_bound`."""
    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    tf = transfer if transfer is not None else resolve_transfer(scene.transfer, volume)
    scene, golden = golden_at_machine(scene, volume, machine, tf)
    plan = make_plan(scene, volume, machine.order)
    fixed = render_functional(frame_of(scene, volume, tf, machine, plan))
    return golden, fixed, pixel_bound(scene, volume, machine, tf)


def pixel_bound(scene, volume, arch, transfer=None) -> np.ndarray:
    """Per pixel and channel, an upper bound on ``|golden - functional|`` for ``scene``
    on ``arch`` at the machine's sample positions (golden rendered as
    :func:`golden_at_machine` renders it); shaped like the images.

    Derived from ``arch``'s datapath formats for ``volume`` (docs/numerics.md); computed
    from the scene's inputs only, never from either image.
    """
    machine = resolve_arch(arch) if isinstance(arch, str) else arch
    chosen = algorithms(machine)
    if scene.render.gradient is None:
        scene = scene.replace(render=dataclasses.replace(scene.render, gradient=chosen.gradient))
    tf = transfer if transfer is not None else resolve_transfer(scene.transfer, volume)
    dp = Datapath.for_volume(machine, volume)
    _refuse_unsupported(scene, tf, dp)
    plan = make_plan(scene, volume, machine.order)
    return Bound(scene, volume, tf, dp, plan).run()


def _refuse_unsupported(scene, tf, dp) -> None:
    r = scene.render
    reasons = [
        (tf.order == "pre" and r.mode == "composite", "pre-classification"),
        (tf.modulates and r.mode == "composite", "gradient-magnitude opacity modulation"),
        (tf.modulates_illumination and scene.lit, "gradient-magnitude illumination"),
        (scene.classification is not None, "multi-LUT classification"),
        (scene.geometry is not None, "embedded geometry"),
        (scene.cursor is not None, "the 3-D cursor"),
        (scene.crop is not None, "crop"),
        (bool(scene.cut_planes), "cut planes"),
        (r.early_termination < 1.0 and r.mode == "composite", "early ray termination"),
        (r.interpolation != "trilinear", f"{r.interpolation} interpolation"),
        (
            scene.render.gradient != dp.gradient.source and scene.lit,
            "a gradient source other than the machine's",
        ),
    ]
    for refused, what in reasons:
        if refused:
            raise NotImplementedError(f"numeric_bound does not cover {what}")
