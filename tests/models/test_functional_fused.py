"""The compiled composite stage (models/fused.py) gives the unit chain's bits.

Three kinds of evidence.  (1) Every ``*_raw`` unit function the kernel calls, compiled
by numba for scalars, equals the same function run by NumPy on arrays, over random and
extreme inputs in every rounding mode: the one source of truth behaves the same in both
worlds (integer types, shifts of negative numbers, floor division, float rounding).
(2) Whole frames rendered with the kernel (``compiled=True``, the default) equal the
vectorised unit chain (``compiled=False``) in image, samples, rays, cycles and counters,
over machines, views, widths, rounding modes, modulation, cut planes, crop, early
termination, anisotropic spacing and supersampling -- and the kernel did run.  (3) The
compiled kernel's cache key covers every unit function it calls.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numba
import numpy as np
import pytest
import rungs

from hwsim.golden import make_plan
from hwsim.numerics import ROUNDING_CODES, round_scaled, round_shift_raw
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import CropSpec, CutPlane, Light, RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models import fused, fused_stage, fused_steps
from models.datapath import Datapath
from models.frame import frame_of
from models.functional import render_functional
from models.units import classify as classify_unit
from models.units import composite as composite_unit
from models.units import gradient as gradient_unit
from models.units import interp as interp_unit
from models.units import shade as shade_unit

pytestmark = pytest.mark.model

# --------------------------------------------------------------------------- scalar = array


def _scalar_map(fn, n_args: int, n_out: int = 1):
    """An njit loop applying ``fn`` (compiled too) to scalars ``args[k][i]`` (int64 or
    float64 arrays); ``n_out`` outputs stacked as rows."""
    args = ", ".join(f"a{k}" for k in range(n_args))
    items = ", ".join(f"a{k}[i]" for k in range(n_args))
    targets = ", ".join(f"out[{k}, i]" for k in range(n_out))
    src = (
        f"def loop({args}, out):\n    for i in range(a0.shape[0]):\n"
        f"        {targets}, = _as_tuple(fn({items}))\n"
    )
    scope = {"fn": numba.njit(fn), "_as_tuple": _AS_TUPLE[n_out > 1]}
    exec(src, scope)
    compiled = numba.njit(scope["loop"])

    def run(*arrays, dtype=np.int64):
        out = np.zeros((n_out, arrays[0].shape[0]), dtype=dtype)
        compiled(*arrays, out)
        return out if n_out > 1 else out[0]

    return run


_AS_TUPLE = {False: numba.njit(lambda r: (r,)), True: numba.njit(lambda r: r)}


def _ints(rng, n, lo, hi, extremes=()):
    x = rng.integers(lo, hi, size=n, dtype=np.int64)
    x[: len(extremes)] = extremes
    return x


@pytest.mark.parametrize("rounding", list(ROUNDING_CODES))
def test_round_shift_raw_compiled_equals_numpy(rounding):
    rng = np.random.default_rng(1)
    code = ROUNDING_CODES[rounding]
    raw = _ints(rng, 5000, -(2**40), 2**40, [0, 1, -1, 7, -7, 8, -8, 2**40 - 1, -(2**40)])
    for shift in (-3, 0, 1, 4, 12, 24):
        scalar = _scalar_map(lambda r, s: round_shift_raw(r, s, code), 2)
        want = round_shift_raw(raw, shift, code)
        np.testing.assert_array_equal(scalar(raw, np.full_like(raw, shift)), want)
        # int32 arrays keep their type and give the int64 integers where they fit.
        small = raw[np.abs(raw) < 2**26].astype(np.int32)
        narrow = round_shift_raw(small, shift, code) if shift > -3 else None
        if narrow is not None:
            np.testing.assert_array_equal(
                narrow, round_shift_raw(small.astype(np.int64), shift, code)
            )


@pytest.mark.parametrize("rounding", list(ROUNDING_CODES))
def test_cell_weight_and_lerps_compiled_equal_numpy(rounding):
    rng = np.random.default_rng(2)
    code = ROUNDING_CODES[rounding]
    p = rng.uniform(-2.0, 70.0, 4000)
    p[:6] = [0.0, -0.0, 63.0, 62.999999999999, 0.5, 63.5]
    p[6:400] = np.round(p[6:400])  # on voxel slices
    for w_bits in (1, 5, 8, 16):
        scalar = _scalar_map(
            lambda x, h, w_bits=w_bits: interp_unit.cell_weight(x, h, w_bits, code), 2, 2
        )
        want = interp_unit.cell_weight(p, 63.0, w_bits, code)
        got = scalar(p, np.full_like(p, 63.0), dtype=np.float64)
        np.testing.assert_array_equal(got, np.stack(want))
    a, b = _ints(rng, 4000, -(2**20), 2**20), _ints(rng, 4000, -(2**20), 2**20)
    for w_bits in (3, 8, 16):
        f = _ints(rng, 4000, 0, (1 << w_bits) + 1, [0, 1 << w_bits])
        lerp = _scalar_map(
            lambda x, y, z, w_bits=w_bits: interp_unit.lerp_raw(x, y, z, w_bits, code), 3
        )
        np.testing.assert_array_equal(lerp(a, b, f), interp_unit.lerp_raw(a, b, f, w_bits, code))
        bil = _scalar_map(
            lambda x, y, z, w_bits=w_bits: interp_unit.bilinear_raw(
                x, y, z, x - z, y, z, w_bits, code
            ),
            3,
        )
        np.testing.assert_array_equal(
            bil(a, b, f), interp_unit.bilinear_raw(a, b, f, a - f, b, f, w_bits, code)
        )
    scaled = rng.uniform(-1000, 1000, 3000)
    scaled[:6] = [0.5, -0.5, 1.5, 2.5, -2.5, 0.0]
    rs = _scalar_map(lambda x, c: round_scaled(x, c), 2)
    np.testing.assert_array_equal(
        rs(scaled, np.full(scaled.shape, code), dtype=np.float64), round_scaled(scaled, code)
    )


@pytest.mark.parametrize("rounding", list(ROUNDING_CODES))
def test_inner_positions_have_the_centres_weights_one_cell_over(rounding):
    """The kernel's gradient fast path (fused._inner): where it holds, interp.cell_weight
    of p + 1 and p - 1 gives the next cells and p's own weight, so the six neighbours are
    the centre's sample moved by one cell; a p + 1 that rounds does not qualify."""
    rng = np.random.default_rng(5)
    code = ROUNDING_CODES[rounding]
    hi = 63.0
    p = rng.uniform(-2.0, 66.0, 20000)
    p[:400] = np.round(p[:400])  # on voxel slices
    binades = 2.0 ** np.arange(1, 7)
    p[400:406] = np.nextafter(binades, 0.0)  # just below a power of two
    p[406:412] = binades - 1.0 + 2.0**-40  # p + 1 lands just above one
    p[412:418] = [1.0, 61.999999999999, 62.0, 0.999999999, 61.0, 2.0**-30]
    crossing = np.array([31.0 + 2.0**-48, 15.0 + 2.0**-49, 7.0 + 2.0**-50])  # p + 1 rounds
    p = np.concatenate([p, crossing])
    inner = _scalar_map(lambda x, h: fused._inner(x, h), 2)(p, np.full_like(p, hi)) == 1
    assert inner.mean() > 0.8 and not inner[-3:].any()
    for w_bits in (1, 5, 8, 16):
        c, w = interp_unit.cell_weight(p, hi, w_bits, code)
        for step in (1.0, -1.0):
            c2, w2 = interp_unit.cell_weight(p + step, hi, w_bits, code)
            np.testing.assert_array_equal(c2[inner], c[inner] + step)
            np.testing.assert_array_equal(w2[inner], w[inner])


def test_gradient_arithmetic_compiled_equals_numpy():
    rng = np.random.default_rng(3)
    g = _ints(rng, 6000, -(2**24), 2**24, [0, 1, -1, 2**24 - 1])
    s = g * g
    isq = _scalar_map(lambda x, _: gradient_unit.isqrt_raw(x), 2)
    np.testing.assert_array_equal(isq(s, s), gradient_unit.isqrt_raw(s))
    bl = _scalar_map(lambda x, _: gradient_unit.bit_length_raw(x), 2)
    m = np.abs(g)
    np.testing.assert_array_equal(bl(m, m), [int(v).bit_length() for v in m])
    n, d = g << 12, np.abs(g[::-1]) + 1
    fd = _scalar_map(lambda x, y: gradient_unit.floor_div_raw(x, y), 2)
    ok = np.abs(n // d) < 2**50
    np.testing.assert_array_equal(fd(n, d)[ok], (n // d)[ok])
    np.testing.assert_array_equal(gradient_unit.floor_div_raw(n, d)[ok], (n // d)[ok])
    gx, gy, gz = g, np.roll(g, 1) >> rng.integers(0, 20, g.size), np.roll(g, 2) >> 17
    gx[:4], gy[:4], gz[:4] = 0, [0, 1, 0, -3], [0, 0, -1, 2]
    for f in (2, 10, 20):
        nr = _scalar_map(lambda x, y, z, f=f: gradient_unit.normal_raw(x, y, z, f), 3, 3)
        want = gradient_unit.normals(
            np.stack([gx, gy, gz], axis=1), gradient_unit.GradientConfig(normal_frac_bits=f)
        )
        np.testing.assert_array_equal(nr(gx, gy, gz).T, want)


def test_shading_classify_and_blend_arithmetic_compiled_equal_numpy():
    rng = np.random.default_rng(4)
    f = 10
    n = rng.integers(-(1 << f), (1 << f) + 1, size=(3, 3000))
    terms = _scalar_map(
        lambda x, y, z: shade_unit.light_terms_raw(
            x, y, z, -300, 512, 700, 100, -20, 1000, 256, 179, 1024, f
        ),
        3,
        2,
    )
    want = shade_unit.light_terms_raw(*n, -300, 512, 700, 100, -20, 1000, 256, 179, 1024, f)
    np.testing.assert_array_equal(terms(*n), np.stack(want))
    c = rng.integers(0, 4097, 3000)
    d, sp = rng.integers(0, 3 * 4096, 3000), rng.integers(0, 4097, 3000)
    sh = _scalar_map(lambda x, y, z: shade_unit.shade_raw(40, x, y, z), 3)
    np.testing.assert_array_equal(sh(c, d, sp), shade_unit.shade_raw(40, c, d, sp))
    sample = _ints(rng, 3000, -100, (4096 << 4) + 100)
    li = _scalar_map(lambda x, _: classify_unit.lut_index_raw(x, 4, 4096), 2)
    np.testing.assert_array_equal(li(sample, sample), classify_unit.lut_index_raw(sample, 4, 4096))
    a = rng.integers(0, 4097, 3000)
    sa = _scalar_map(lambda x, y: classify_unit.scale_alpha_raw(x, y), 2)
    np.testing.assert_array_equal(sa(a, c), classify_unit.scale_alpha_raw(a, c))
    gi = _scalar_map(lambda x, _: classify_unit.gm_index_raw(x, 12345678, 64), 2)
    m = rng.integers(0, 2**20, 3000)
    np.testing.assert_array_equal(gi(m, m), classify_unit.gm_index_raw(m, 12345678, 64))
    acc_a = rng.integers(0, (1 << 16) + 1, 3000)
    for rounding, code in ROUNDING_CODES.items():
        w = _scalar_map(
            lambda x, y, code=code: composite_unit.ftb_weight_raw(x, y, 1 << 16, code), 2
        )
        want_w = composite_unit.ftb_weight_raw(acc_a, a, 1 << 16, code)
        np.testing.assert_array_equal(w(acc_a, a), want_w, err_msg=rounding)
        col = _scalar_map(lambda x, y, code=code: composite_unit.ftb_colour_raw(x, y, code), 2)
        np.testing.assert_array_equal(
            col(want_w, c), composite_unit.ftb_colour_raw(want_w, c, code)
        )


def test_the_cache_key_covers_every_unit_function_the_kernel_calls():
    """The kernels call unit functions and inline the shared stage (models/fused_stage.py):
    the stage's hash covers both, and it is a closure value of every kernel."""
    source = Path(fused.__file__).read_text() + Path(fused_stage.__file__).read_text()
    called = set(re.findall(r"\b(\w+_unit)\.(\w+_raw)\(", source))
    registered = {fn.__name__ for fn in fused_stage._UNIT_FUNCTIONS}
    assert {name for _, name in called} <= registered
    assert {"round_shift_raw", "round_scaled", "cell_weight"} <= registered
    assert len(fused.UNITS_HASH) == 64 and len(fused.STAGE_HASH) == 64
    stage_source = Path(fused_stage.__file__).read_text(encoding="utf-8")
    expected = hashlib.sha256((fused.UNITS_HASH + stage_source).encode()).hexdigest()
    assert fused.STAGE_HASH == expected
    # The hash is a closure value of every kernel (numba's cache key holds closure
    # values), next to the configuration's constants when specialised.
    config = (4, 8, 1, 4, 4096, 10, 1024, 1 << 16, 1)
    for key in (config, None):
        kernel = fused._kernel_for(key)
        cells = [c.cell_contents for c in kernel.py_func.__closure__]
        assert fused.STAGE_HASH in cells
        assert (config in cells) == (key is not None)


def test_only_a_machines_own_formats_get_a_specialised_kernel(monkeypatch):
    volume = make_phantom("head", size=12)
    scene = _scene(size=16)
    seen = []
    original = fused._kernel_for
    monkeypatch.setattr(fused, "_kernel_for", lambda key: seen.append(key) or original(key))
    _render("volumepro500", volume, scene, {})
    _render("volumepro500", volume, scene, {"interp.weight_bits": 6})
    _render("volumepro500", volume, scene, {"gradient.normal_frac_bits": 8})
    assert seen[0] is not None and seen[0][1] == 8  # specialised: S, weight bits 8, ...
    assert seen[1:] == [None, None]  # a width sweep shares the generic kernel


# --------------------------------------------------------------------------- whole frames


def _scene(mode="composite", transfer=None, az=30, el=20, size=40, **kw):
    return Scene(
        transfer=transfer or TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=size, height=size, zoom=kw.pop("zoom", 1.3)),
        render=RenderSpec(mode=mode, **kw.pop("render", {})),
        **kw,
    )


GRADIENT_OPACITY = ((100.0, 0.0), (1500.0, 1.0))
CUT = (CutPlane(normal=(0.3, 0.2, 1.0), offset=1.0, thickness=6, falloff=3),)
TWO_LIGHTS = (
    Light(direction=(-0.4, 0.5, 1.0)),
    Light(direction=(0.7, -0.2, 0.5), intensity=0.6),
)
#: (machine, volume, scene, format overrides); every one runs the kernel.
CASES = {
    "vp500": ("volumepro500", "head", _scene(), {}),
    "vp500-axis": ("volumepro500", "head", _scene(az=0, el=0), {}),
    "vp500-45-45": ("volumepro500", "head", _scene(az=45, el=45), {}),
    "vp500-back": ("volumepro500", "head", _scene(az=180, el=-35), {}),
    "vp500-anisotropic": ("volumepro500", "head-z", _scene(az=-60, el=30), {}),
    "vp500-modulated-ert": (
        "volumepro500",
        "head",
        _scene(
            transfer=TransferSpec(preset="ct", gradient_opacity=GRADIENT_OPACITY),
            render={"early_termination": 0.7},
        ),
        {},
    ),
    "vp500-crop-cut": (
        "volumepro500",
        "head",
        _scene(crop=CropSpec(y=(4, 15), invert=True), cut_planes=CUT),
        {},
    ),
    "vp500-supersampled": ("volumepro500", "head", _scene(render={"supersampling": 2.0}), {}),
    "vp500-unlit-two-lights": ("volumepro500", "head", _scene(lights=TWO_LIGHTS), {}),
    "em-cube": ("em-cube", "head", _scene(az=100, el=10), {}),
    "cube4": ("cube4", "head", _scene(), {}),
    "vp1000-voxel-gradients": ("volumepro1000", "head", _scene(az=-20, el=60), {}),
    # x principal: the kernel reads voxels and differences laid out x-slowest.
    "vp1000-x-principal": ("volumepro1000", "head-z", _scene(az=95, el=-5), {}),
    "vp1000-supersampled-cut": (
        "volumepro1000",
        "head",
        _scene(cut_planes=CUT, render={"supersampling": 3.0}),
        {},
    ),
    "vizard2-ert": ("vizard2", "head", _scene(az=40, el=25, render={"early_termination": 0.9}), {}),
    "vizard2-perspective-unlit": (
        "vizard2",
        "head",
        Scene(
            transfer=TransferSpec(preset="ct"),
            view=ViewSpec(azimuth=-30, elevation=10, width=40, height=40, projection="perspective"),
            render=RenderSpec(lighting=False),
        ),
        {},
    ),
    "nearest-even-narrow": (
        "volumepro500",
        "head",
        _scene(az=-70, el=25),
        rungs.NARROW_NEAREST_EVEN,
    ),
    "int64-lerps-truncate": (
        "volumepro500",
        "head",
        _scene(transfer=TransferSpec(preset="ct", gradient_opacity=GRADIENT_OPACITY)),
        {**rungs.WIDE_TRUNCATE, "shade.spec_table_entries": 16},
    ),
}


@pytest.fixture(scope="module")
def volumes():
    return {
        "head": make_phantom("head", size=21),
        "head-z": make_phantom("head", size=24, z_spacing=1.7),
    }


def _render(arch_name, volume, scene, overrides, **kw):
    arch = resolve_arch(arch_name)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, arch.order)
    bits = volume.bits if volume.data.dtype.kind in "iu" else 0
    dp = Datapath.from_arch(arch, bits, overrides)
    return render_functional(frame_of(scene, volume, tf, arch, plan, datapath=dp), **kw)


@pytest.mark.parametrize("case", list(CASES))
def test_compiled_frames_equal_the_unit_chain(case, volumes, monkeypatch):
    arch, volume, scene, overrides = CASES[case]
    runs = []
    original = fused.CompositeKernel.run_part

    settled = []

    def counted(self, zyx, rays, factor, state, table):
        runs.append(rays.size)
        sat = original(self, zyx, rays, factor, state, table)
        settled.append(int(sat[2]))
        return sat

    walked = []
    original_walk = fused_steps.run_steps_compiled

    def walk(*args):
        walked.append(True)
        return original_walk(*args)

    monkeypatch.setattr(fused.CompositeKernel, "run_part", counted)
    monkeypatch.setattr(fused_steps, "run_steps_compiled", walk)
    fast = _render(arch, volumes[volume], scene, overrides)
    assert sum(runs) > 0, "the kernel did not run"
    ref = _render(arch, volumes[volume], scene, overrides, compiled=False)
    np.testing.assert_array_equal(fast.image, ref.image)
    assert (fast.samples, fast.rays, fast.cycles) == (ref.samples, ref.rays, ref.cycles)
    assert fast.counters == ref.counters
    # Frames without masks take the compiled step walker, which skips
    # unoccupied blocks per sample (inside rays too): never more samples than the chain's
    # plan leap simulates.  Everything else walks the leapt plan, as the chain does.
    expect_walk = scene.crop is None and not scene.cut_planes
    assert bool(walked) == expect_walk
    if walked:
        assert 0 < fast.simulated <= ref.simulated
    else:
        assert fast.simulated == ref.simulated
    assert ref.image[..., 3].max() > 0.05  # something was composited
    if case in SETTLING:  # the kernel skipped samples of settled rays, and got the same bits
        assert sum(settled) > 0


#: Cases whose opaque rays settle (their blend weight rounds to 0) inside the volume.
SETTLING = ("vp500", "vp500-axis", "cube4")


def test_settled_rays_are_skipped_only_where_the_weight_is_known_early(volumes, monkeypatch):
    """Back to front or with gradient-modulated opacity a sample's blend weight is not
    known before its gradient: nothing is skipped there (and the frames still equal the
    chain's, test_compiled_frames_equal_the_unit_chain)."""
    settled = []
    original = fused.CompositeKernel.run_part

    def counted(self, zyx, rays, factor, state, table):
        sat = original(self, zyx, rays, factor, state, table)
        settled.append(int(sat[2]))
        return sat

    monkeypatch.setattr(fused.CompositeKernel, "run_part", counted)
    arch, volume, scene, overrides = CASES["vp500-modulated-ert"]
    _render(arch, volumes[volume], scene, overrides)
    assert settled and sum(settled) == 0


@pytest.mark.parametrize(
    "arch, scene, overrides",
    [
        ("volumepro500", _scene(transfer=TransferSpec(preset="ct", order="pre")), {}),
        ("volumepro500", _scene("mip"), {}),
        ("volumepro500", _scene("iso", render={"iso_value": 200.0}), {}),
    ],
    ids=["pre-classified", "mip", "iso"],
)
def test_frames_outside_the_kernels_scope_take_the_unit_chain(arch, scene, overrides, volumes):
    from models.backend import Backend
    from models.functional import _Functional

    volume = volumes["head"]
    machine = resolve_arch(arch)
    tf = resolve_transfer(scene.transfer, volume)
    plan = make_plan(scene, volume, machine.order)
    dp = Datapath.from_arch(machine, volume.bits, overrides)
    rung = _Functional(Backend(frame_of(scene, volume, tf, machine, plan, datapath=dp)))
    assert rung.kernel is None
    fast = _render(arch, volume, scene, overrides)
    ref = _render(arch, volume, scene, overrides, compiled=False)
    np.testing.assert_array_equal(fast.image, ref.image)


@numba.njit
def _plane_and_direct(kernel_vox, strides, offsets, shape, kp, zyx, config):
    """The kernel's plane for one step's samples (``fused._plane``) and the direct
    ``fused._trilinear`` call at every cell of its box."""
    s_bits, w_bits, w_code = config[0], config[1], config[2]
    n = zyx.shape[0]
    hi = (shape[0] - 1.0, shape[1] - 1.0, shape[2] - 1.0)
    cw = np.empty((6, n), np.int64)
    for i in range(n):
        for a in range(3):
            c, q = interp_unit.cell_weight(zyx[i, a], hi[a], w_bits, w_code)
            cw[a, i], cw[3 + a, i] = np.int64(c), np.int64(q)
    plane, key, box = fused._plane(
        kernel_vox, strides, offsets, shape, kp, cw, s_bits, w_bits, w_code
    )
    direct = np.empty_like(plane)
    a_ax, b_ax, a_lo, b_lo, pw = box[0], box[1], box[2], box[3], box[4]
    o1, o2, o3, o4 = offsets[1], offsets[2], offsets[3], offsets[4]
    shared = 0
    for i in range(n):
        if pw > 0 and cw[kp, i] == key[0] and cw[3, i] == key[1]:
            if cw[4, i] == key[2] and cw[5, i] == key[3]:
                shared += 1
    for e in range(plane.size):
        ia, ib = a_lo + e // max(pw, 1), b_lo + e % max(pw, 1)
        base = key[0] * strides[kp] + ia * strides[a_ax] + ib * strides[b_ax]
        direct[e] = fused._trilinear(
            kernel_vox, base, o1, o2, o3, o4, key[1], key[2], key[3], s_bits, w_bits, w_code
        )
    return plane, direct, shared


@pytest.mark.parametrize(
    "case", ["vp500", "vp500-axis", "vp500-anisotropic", "vp500-supersampled", "em-cube", "cube4",
             "nearest-even-narrow"],
)  # fmt: skip
def test_a_steps_plane_holds_the_direct_samples_of_its_cells(case, volumes, monkeypatch):
    """Shear-warp's shared weights (fused._plane): every entry of a step's plane is the
    direct trilinear call at its cell and the step's weights, bit for bit (on voxel
    slices the plane's rows of lerps, fused._slice_plane; supersampled, the trilinear
    itself), and the planes hold most of the kernel's samples.  (Shear-image steps, as
    VolumePro 1000's, have a ray's own weights: no plane, the direct calls.)"""
    arch, volume, scene, overrides = CASES[case]
    steps = []
    original = fused.CompositeKernel.run_part

    def captured(self, zyx, rays, factor, state, table):
        steps.append((self, zyx.copy()))
        return original(self, zyx, rays, factor, state, table)

    monkeypatch.setattr(fused.CompositeKernel, "run_part", captured)
    _render(arch, volumes[volume], scene, overrides)
    entries = held = samples = 0
    for kernel, zyx in steps:
        assert kernel.kp >= 0
        config = np.asarray(kernel.config, dtype=np.int64)
        plane, direct, shared = _plane_and_direct(
            kernel.vox, kernel.strides, kernel.offsets, kernel.shape, kernel.kp, zyx, config
        )
        np.testing.assert_array_equal(plane, direct)
        entries += plane.size
        held += shared if plane.size else 0
        samples += zyx.shape[0]
    assert entries > 0 and held > samples // 2
