"""The functional rung's fast paths are exact: skipped work and narrower arithmetic never
change a bit.

Two kinds of evidence.  (1) The interpolator's fast paths (int32 promotion, lerps dropped
where every weight is 0 or 1.0, the shared six-neighbour gradient gather) against a
per-sample oracle written with Python integers.  (2) Whole renders with block leaping
(``leap_blocks=True``, the default) against the reference loop that pushes every planned
sample through the back end (``leap_blocks=False``): image, samples, rays, cycles and
counters identical, over the cases where a wrong rule would show (pre-classification,
gradient-opacity modulation, early termination, crop, cut planes, iso, perspective
steps, supersampling), and on a transfer function with one opaque entry inside a
transparent range, where a plausible wrong rule is shown to change the image.
"""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.golden import make_plan
from hwsim.golden.occupancy import occupancy_from_ranges
from hwsim.numerics import ROUNDINGS, round_shift
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import CropSpec, CutPlane, RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from hwsim.volumes.volume import Volume
from models import fused_steps, leap
from models.frame import frame_of
from models.functional import render_functional
from models.units import classify as classify_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units.interp import InterpConfig

pytestmark = pytest.mark.model

CONFIGS = [
    InterpConfig(),
    InterpConfig(weight_bits=5, sample_frac_bits=2, rounding="nearest-even"),
    InterpConfig(weight_bits=9, sample_frac_bits=1, rounding="truncate"),
    InterpConfig(weight_bits=3, sample_frac_bits=6, rounding="floor"),
    InterpConfig(weight_bits=16, sample_frac_bits=12),  # too wide for int32: int64 path
]


# --------------------------------------------------------------------------- oracle


def _round(x: int, w: int, rounding: str) -> int:
    """``x / 2**w`` rounded, in Python integers (independent of hwsim.numerics)."""
    q, r = divmod(x, 1 << w)  # floor division
    half = 1 << (w - 1)
    if rounding == "floor":
        return q
    if rounding == "truncate":
        return q + 1 if x < 0 and r else q
    if rounding == "nearest-up":
        return q + 1 if r >= half else q
    return q + 1 if r > half or (r == half and q % 2) else q  # nearest-even


def _oracle_sample(flat, shape, p, cfg: InterpConfig) -> int:
    """One trilinear sample, the unit's documented rule, corner by corner."""
    cells = []
    for axis in range(3):
        n = shape[axis]
        c = min(max(float(p[axis]), 0.0), n - 1.0)
        i0 = int(min(np.floor(c), max(n - 2, 0)))
        f = int(cfg.weight.quantize(np.array([c - i0]))[0])
        cells.append((i0, min(i0 + 1, n - 1), f))
    (z0, z1, fz), (y0, y1, fy), (x0, x1, fx) = cells
    w, s = cfg.weight_bits, cfg.sample_frac_bits

    def v(z, y, x):
        return int(flat[(z * shape[1] + y) * shape[2] + x]) << s

    def lerp(a, b, f):
        return a + _round((b - a) * f, w, cfg.rounding)

    ys = []
    for z in (z0, z1):
        ys.append(
            lerp(lerp(v(z, y0, x0), v(z, y0, x1), fx), lerp(v(z, y1, x0), v(z, y1, x1), fx), fy)
        )
    return lerp(ys[0], ys[1], fz)


def _positions(rng, shape, kind: str, n: int = 120) -> np.ndarray:
    zyx = rng.uniform(-0.6, 1.0, size=(n, 3)) * (np.asarray(shape) + 0.2)
    zyx[: n // 6] = np.round(zyx[: n // 6])  # on voxel centres
    zyx[n // 6 : n // 3] = np.nextafter(np.round(zyx[n // 6 : n // 3]), -np.inf)
    if kind == "slice":  # every sample on one voxel slice: the z lerp is dropped
        zyx[:, 0] = np.round(zyx[:, 0])
    elif kind == "last-slice":  # weight 1.0 along z for every sample
        zyx[:, 0] = shape[0] - 1.0
    elif kind == "two-axes":
        zyx[:, 0] = np.round(zyx[:, 0])
        zyx[:, 2] = shape[2] - 1.0
    return zyx


@pytest.mark.parametrize("cfg", CONFIGS, ids=lambda c: f"w{c.weight_bits}s{c.sample_frac_bits}")
@pytest.mark.parametrize("shape", [(1, 1, 1), (1, 5, 7), (7, 1, 5), (9, 11, 6)])
@pytest.mark.parametrize("kind", ["free", "slice", "last-slice", "two-axes"])
def test_interpolation_and_sample_gradient_fast_paths_equal_the_oracle(cfg, shape, kind):
    rng = np.random.default_rng(hash((shape, kind, cfg.weight_bits)) % 2**32)
    flat = rng.integers(-5000, 5000, size=int(np.prod(shape)))
    zyx = _positions(rng, shape, kind)
    want = [_oracle_sample(flat, shape, p, cfg) for p in zyx]
    ahead_behind = []
    for axis in range(3):
        e = np.zeros(3)
        e[axis] = 1.0
        ahead = [_oracle_sample(flat, shape, p + e, cfg) for p in zyx]
        behind = [_oracle_sample(flat, shape, p - e, cfg) for p in zyx]
        ahead_behind.append(np.subtract(ahead, behind))
    want_g = np.stack(ahead_behind[::-1], axis=1)  # (x, y, z) components
    promoted = interp_unit.promote(flat, cfg)
    taps = interp_unit.interp_taps(zyx, shape, cfg)
    for src, is_promoted in ((flat, False), (promoted, True)):
        got = interp_unit.interpolate(src, taps, cfg, promoted=is_promoted)
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, want)
        g = gradient_unit.sample_differences(src, zyx, shape, cfg, promoted=is_promoted)
        assert g.dtype == np.int64
        np.testing.assert_array_equal(g, want_g)
        # The sample's own cells handed over from its taps (as the functional rung does).
        g = gradient_unit.sample_differences(
            src, zyx, shape, cfg, promoted=is_promoted, center=(taps.cells, taps.frac)
        )
        np.testing.assert_array_equal(g, want_g)
    # Explicit (8, n) indices, as the RTL bench builds them, take the same path.
    explicit = interp_unit.InterpTaps(taps.idx, taps.frac)
    np.testing.assert_array_equal(interp_unit.interpolate(flat, explicit, cfg), want)


def test_lerp_plan_drops_only_axes_whose_weight_is_uniformly_0_or_1():
    cfg = InterpConfig()
    one = 1 << cfg.weight_bits
    frac = np.array([[0, 0, 0], [one, one, one], [3, 0, one]])
    free, corners = interp_unit.lerp_plan(frac, cfg)
    assert free == [2] and corners == [2, 3]  # dz = 0, dy = 1, dx free
    free, corners = interp_unit.lerp_plan(np.array([[0, one], [1, 1], [0, 0]]), cfg)
    assert free == [0, 1] and corners == [0, 2, 4, 6]


def test_promotion_is_int32_only_when_every_lerp_fits():
    assert interp_unit.promote(np.array([0, 4095]), InterpConfig()).dtype == np.int32
    assert interp_unit.promote(np.array([-16383, 16383]), InterpConfig()).dtype == np.int32
    wide = InterpConfig(weight_bits=16, sample_frac_bits=12)
    assert interp_unit.promote(np.array([0, 4095]), wide).dtype == np.int64
    # The bound is (2 M + 1) 2**W < 2**31, M the largest promoted magnitude.
    cfg = InterpConfig(weight_bits=8, sample_frac_bits=4)
    m = ((1 << 23) - 1) // 2 >> 4  # largest raw value with (2 M + 1) 2**8 < 2**31
    assert interp_unit.promote(np.array([m]), cfg).dtype == np.int32
    assert interp_unit.promote(np.array([m + 1]), cfg).dtype == np.int64


@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_round_shift_keep_dtype_gives_the_int64_integers(rounding):
    rng = np.random.default_rng(7)
    raw = rng.integers(-(2**30), 2**30, size=4000).astype(np.int32)
    raw[:8] = [0, 1, -1, 127, 128, -128, 2**30 - 1, -(2**30)]
    for shift in (1, 4, 8, 12):
        narrow = round_shift(raw, shift, rounding, keep_dtype=True)
        assert narrow.dtype == np.int32
        np.testing.assert_array_equal(narrow, round_shift(raw, shift, rounding))


# --------------------------------------------------------------------------- whole renders


def _render(scene, volume, arch="volumepro500", **kw):
    machine = resolve_arch(arch)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    return render_functional(frame_of(scene, volume, tf, machine, plan), **kw)


def assert_same_run(fast, ref):
    assert fast.image.dtype == ref.image.dtype
    np.testing.assert_array_equal(fast.image, ref.image)
    assert (fast.samples, fast.rays, fast.cycles) == (ref.samples, ref.rays, ref.cycles)
    assert fast.counters == ref.counters


@pytest.fixture(scope="module")
def head21():
    return make_phantom("head", size=21)  # odd: blocks of 4 do not tile it


def _scene(mode="composite", transfer=None, projection="parallel", az=30, el=20, size=40, **kw):
    return Scene(
        transfer=transfer or TransferSpec(preset="ct"),
        view=ViewSpec(
            azimuth=az,
            elevation=el,
            width=size,
            height=size,
            zoom=kw.pop("zoom", 1.3),
            projection=projection,
        ),
        render=RenderSpec(mode=mode, **kw.pop("render", {})),
        **kw,
    )


GRADIENT_OPACITY = ((100.0, 0.0), (1500.0, 1.0))
CASES = {
    "post": ("volumepro500", _scene()),
    "pre-classified": ("volumepro500", _scene(transfer=TransferSpec(preset="ct", order="pre"))),
    "gradient-opacity": (
        "volumepro500",
        _scene(transfer=TransferSpec(preset="ct", gradient_opacity=GRADIENT_OPACITY)),
    ),
    "early-termination": ("volumepro500", _scene(render={"early_termination": 0.6})),
    "crop-and-ert": (
        "volumepro500",
        _scene(crop=CropSpec(y=(4, 15), invert=True), render={"early_termination": 0.8}),
    ),
    "cut-plane": (
        "volumepro1000",
        _scene(cut_planes=(CutPlane(normal=(0.3, 0.2, 1.0), offset=1.0, thickness=6, falloff=3),)),
    ),
    "iso": ("volumepro500", _scene("iso", render={"iso_value": 200.0})),
    "supersampled": ("volumepro500", _scene(render={"supersampling": 2.0})),
    # Per-ray steps: these two fail without the work-around in models.leap.leapt_plan.
    "perspective-cube4": ("cube4", _scene(projection="perspective", size=28, zoom=1.2)),
    "perspective-vp1000-ert-a": (
        "volumepro1000",
        _scene(projection="perspective", size=28, zoom=1.2, render={"early_termination": 0.7}),
    ),
    "perspective-vp1000-ert-b": (
        "volumepro1000",
        _scene(projection="perspective", az=150, el=-30, render={"early_termination": 0.5}),
    ),
    "perspective-vizard2-iso": (
        "vizard2",
        _scene("iso", projection="perspective", az=45, el=0, render={"iso_value": 200.0}),
    ),
    "mip-not-skipped": ("volumepro500", _scene("mip")),
}


@pytest.mark.parametrize("case", list(CASES))
def test_leaping_changes_nothing_but_the_work(head21, case):
    arch, scene = CASES[case]
    fast = _render(scene, head21, arch)
    ref = _render(scene, head21, arch, leap_blocks=False)
    assert_same_run(fast, ref)
    assert ref.simulated == ref.samples
    if scene.render.mode == "mip":
        assert fast.simulated == fast.samples  # every sample counts in a maximum
    else:
        assert fast.simulated < fast.samples  # the head's air was skipped


def _spike_volume(n: int = 24) -> Volume:
    """12-bit ramp 1900..2100 along x with a gentle wobble: blocks span ~70 values, so the
    value 2000 falls strictly inside many blocks' ranges."""
    z, y, x = np.meshgrid(*[np.arange(n, dtype=np.float64)] * 3, indexing="ij")
    data = 1900 + 200 * x / (n - 1) + 15 * np.sin(0.7 * y + 0.4 * z)
    return Volume(data=np.round(data).astype(np.uint16), bits=12, name="spike-ramp")


SPIKE = TransferSpec(
    preset=None,
    points=(
        (0.0, 0.0, 0.0, 0.0, 0.0),
        (1999.0, 0.0, 0.0, 0.0, 0.0),
        (2000.0, 1.0, 0.8, 0.6, 1.0),
        (2001.0, 0.0, 0.0, 0.0, 0.0),
        (4095.0, 0.0, 0.0, 0.0, 0.0),
    ),
)


def _endpoints_only(backend):
    """A plausible wrong rule: look at the LUT only at the ends of each block's range."""
    lo, hi = leap._raw_block_ranges(backend.volume, backend.dp.voxel_bits)
    frac = 0 if backend.pre_classified else backend.S
    alpha = backend.lut.alpha12
    ends = [
        classify_unit.lut_index(r << frac, backend.dp.voxel_bits, frac, backend.dp.classify)
        for r in (lo, hi)
    ]
    return occupancy_from_ranges((alpha[ends[0]] > 0) | (alpha[ends[1]] > 0))


@pytest.mark.parametrize("order", ["post", "pre"])
def test_one_opaque_entry_inside_a_transparent_range_is_never_skipped(order, monkeypatch):
    volume = _spike_volume()
    scene = _scene(transfer=TransferSpec(preset=None, points=SPIKE.points, order=order))
    ref = _render(scene, volume, leap_blocks=False)
    assert ref.image[..., 3].max() > 0.1  # the opaque sheet is in the picture
    fast = _render(scene, volume)
    assert_same_run(fast, ref)
    assert fast.simulated < fast.samples
    # The scene does discriminate: the endpoint-only rule loses part of the sheet.
    monkeypatch.setattr(leap, "invisible_blocks", _endpoints_only)
    wrong = _render(scene, volume)
    assert not np.array_equal(wrong.image, ref.image)


def _clear_cells_oracle(backend) -> np.ndarray:
    """Clear cells ``(z, y, x)`` by NumPy: the smallest and largest voxel of each cell
    (voxel ``i`` and ``i + 1`` along every axis, clamped), their LUT entries, and no entry
    between them with non-zero opacity."""
    lo = hi = np.asarray(backend.raw, dtype=np.int64)
    for axis in range(3):
        n = lo.shape[axis]
        ahead = np.minimum(np.arange(n) + 1, n - 1)
        lo = np.minimum(lo, np.take(lo, ahead, axis=axis))
        hi = np.maximum(hi, np.take(hi, ahead, axis=axis))
    dp = backend.dp
    first, last = (
        classify_unit.lut_index(v << backend.S, dp.voxel_bits, backend.S, dp.classify)
        for v in (lo, hi)
    )
    alpha = backend.lut.alpha12
    visible = np.concatenate([[0], np.cumsum(alpha > 0)])  # visible entries before i
    return visible[last + 1] - visible[first] == 0


@pytest.mark.parametrize(
    "volume, transfer, az",
    [("spike", SPIKE, 30), ("head", None, 30), ("head", None, 95)],
    ids=["spike", "head-z-principal", "head-x-principal"],
)
def test_clear_cells_are_those_whose_samples_are_all_transparent(head21, volume, transfer, az):
    """The compiled walker's clear-cell map (fused_steps.clear_cells), in the kernel's
    voxel layout, equals a direct count (the spike's opaque entry lies strictly inside
    many cells' ranges: a rule that looked only at the ends would clear them)."""
    from models.backend import Backend
    from models.functional import _Functional

    vol = _spike_volume() if volume == "spike" else head21
    scene = _scene(transfer=transfer, az=az, el=0)
    machine = resolve_arch("volumepro500")
    tf = resolve_transfer(scene.transfer, vol)
    backend = Backend(frame_of(scene, vol, tf, machine, make_plan(scene, vol, machine.order)))
    kernel = _Functional(backend).kernel
    cells, strides = fused_steps.clear_cells(kernel)
    z, y, x = np.indices(vol.shape)
    got = cells[z * strides[0] + y * strides[1] + x * strides[2]] == 1
    want = _clear_cells_oracle(backend)
    np.testing.assert_array_equal(got, want)
    assert want.any() and not want.all()


def test_a_clear_cell_map_in_a_new_layout_is_laid_out_from_another(monkeypatch):
    """A turntable whose principal axis moves gets the next layout's clear-cell map from
    the one it holds (no second pass over the voxels), the same bytes as a fresh map."""
    from models.backend import Backend
    from models.functional import _Functional

    vol = make_phantom("head", size=21)  # this test's own: no maps from other tests
    machine = resolve_arch("volumepro500")

    def kernel_at(az):
        scene = _scene(az=az, el=0)
        tf = resolve_transfer(scene.transfer, vol)
        plan = make_plan(scene, vol, machine.order)
        return _Functional(Backend(frame_of(scene, vol, tf, machine, plan))).kernel

    z_kernel, x_kernel = kernel_at(30), kernel_at(95)
    assert not np.array_equal(z_kernel.strides, x_kernel.strides)  # two layouts
    passes = []
    compute = fused_steps._clear_cell_map
    monkeypatch.setattr(fused_steps, "_clear_cell_map", lambda *a: passes.append(1) or compute(*a))
    fused_steps.clear_cells(z_kernel)
    relaid, strides = fused_steps.clear_cells(x_kernel)
    assert len(passes) == 1
    fused_steps._CELLS.pop(vol)
    fresh, fresh_strides = fused_steps.clear_cells(x_kernel)
    assert len(passes) == 2
    np.testing.assert_array_equal(strides, fresh_strides)
    assert relaid.tobytes() == fresh.tobytes() and 0 < fresh.sum() < fresh.size


def test_the_walker_skips_clear_cells_and_nothing_changes(head21, monkeypatch):
    scene = CASES["post"][1]
    fast = _render(scene, head21)
    monkeypatch.setattr(fused_steps, "clear_cells", lambda kernel: None)
    blocks_only = _render(scene, head21)
    assert_same_run(fast, blocks_only)
    assert fast.simulated < blocks_only.simulated < fast.samples


def test_rays_that_meet_only_transparent_samples_are_still_touched():
    """A ray through the box that meets only air: skipped entirely, still counted."""
    volume = _spike_volume()
    scene = _scene(transfer=SPIKE, az=90, el=0)  # rays along x cross the opaque sheet once
    scene = scene.replace(view=ViewSpec(azimuth=20, elevation=10, width=40, height=40))
    ref = _render(scene, volume, "vizard2", leap_blocks=False)  # image pixel = ray
    fast = _render(scene, volume, "vizard2")
    assert_same_run(fast, ref)
    lit = int(np.count_nonzero(ref.image[..., 3] > 0))
    assert 0 < lit < fast.rays  # some touched rays met only transparent samples
    assert fast.simulated < fast.samples


def test_closed_form_step_counts_equal_iterating_the_plan(head21):
    for arch, projection in (("volumepro500", "parallel"), ("volumepro1000", "perspective")):
        scene = _scene(projection=projection)
        plan = make_plan(scene, head21, resolve_arch(arch).order)
        sizes = [step.rays.size for step in plan.steps()]
        np.testing.assert_array_equal(leap.step_sample_counts(plan), sizes)


def _oracle_normal(g, f: int) -> list[int]:
    """The gradient unit's documented normal of one vector, in Python integers."""
    import math

    m0 = math.isqrt(sum(c * c for c in g))
    if m0 == 0:
        return [0, 0, 0]
    shift = min(max(f + 2 - m0.bit_length(), 0), 40)
    g = [c << shift for c in g]
    m = math.isqrt(sum(c * c for c in g))
    limit = 1 << f
    return [min(max((2 * (-c << f) + m) // (2 * m), -limit), limit) for c in g]


@pytest.mark.parametrize("scale", [1, 7, 300, 5000, 2**20])
def test_normals_equal_the_oracle_with_mixed_shifted_and_unshifted_rows(scale):
    rng = np.random.default_rng(scale)
    g = rng.integers(-scale, scale + 1, size=(400, 3))
    g[:5] = 0
    g[5:200] *= rng.integers(1, 4000, size=(195, 1))  # large rows: no normaliser shift
    g = np.clip(g, -(2**24), 2**24)  # the unit's domain: |g|^2 fits int64
    for f in (2, 10, 20):
        got = gradient_unit.normals(g, gradient_unit.GradientConfig(normal_frac_bits=f))
        np.testing.assert_array_equal(got, [_oracle_normal([int(c) for c in row], f) for row in g])


def test_empty_batches_give_empty_results():
    cfg = InterpConfig()
    flat, none = np.arange(27), np.empty((0, 3))
    taps = interp_unit.interp_taps(none, (3, 3, 3), cfg)
    assert interp_unit.interpolate(flat, taps, cfg).shape == (0,)
    assert gradient_unit.sample_differences(flat, none, (3, 3, 3), cfg).shape == (0, 3)
