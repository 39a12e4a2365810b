"""Per-unit test cases shared by the Amaranth-simulator and cocotb tiers: how to build the
RTL, its static configuration and table loads, random plus extreme stimulus, and the
reference -- the unit's own ``models.units`` functions, called on the monitored inputs.

Stimulus and expected values are dicts of int64 arrays keyed by payload field, packed by
the RTL module's own layouts (:mod:`stream_bench`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from stream_bench import pack

from hwsim.numerics import SATURATIONS
from models.units import classify as classify_model
from models.units import composite as composite_model
from models.units import gradient as gradient_model
from models.units import interp as interp_model
from models.units import shade as shade_model
from models.units import skew as skew_model
from rtl import classify, composite, gradient, interp, shade, skew, slice_interp

__all__ = ["UNITS", "COSIM_CASES", "UnitCase", "make_case"]

UNITS = ("skew", "interp", "gradient", "classify", "shade", "composite")
#: What the cocotb tier runs: every unit at its default, plus the per-sample Phong shader.
COSIM_CASES = (*UNITS, "shade_phong")


@dataclass
class UnitCase:
    """Everything a bench needs to run one unit against its model."""

    name: str
    build: Callable
    latency: int
    ii: int
    in_layout: object
    out_layout: object
    stimulus: Callable[[np.random.Generator, int], dict]
    model: Callable[[dict], dict]
    statics: dict[str, int] = field(default_factory=dict)
    load_layout: object = None
    loads: list[int] = field(default_factory=list)


def _keep_saturation_log(fn):
    """Run a model function without leaving counts in the process-wide saturation log."""

    def wrapped(*args):
        saved = SATURATIONS.copy()
        try:
            return fn(*args)
        finally:
            SATURATIONS.clear()
            SATURATIONS.update(saved)

    return wrapped


def _concat(*parts: dict) -> dict:
    return {k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in parts[0]}


def _unit_case(
    name: str,
    build: Callable,
    timing,
    rtl_module,
    in_args: tuple,
    stimulus: Callable,
    model: Callable,
    out_args: tuple | None = None,
    **rest,
) -> UnitCase:
    """A :class:`UnitCase` whose latency and II are ``timing``'s and whose layouts are
    ``rtl_module``'s ``input_layout(*in_args)`` and ``output_layout(*out_args)``
    (``out_args`` defaults to ``in_args``); ``rest``: the other fields by name."""
    out_args = in_args if out_args is None else out_args
    return UnitCase(
        name,
        build,
        timing.LATENCY,
        timing.II,
        rtl_module.input_layout(*in_args),
        rtl_module.output_layout(*out_args),
        stimulus,
        model,
        **rest,
    )


# ------------------------------------------------------------------------------- skew


def skew_case(cfg=None, n: int = 200) -> UnitCase:
    cfg = cfg or skew_model.SkewConfig()
    if not 1 <= n <= cfg.max_size:
        raise ValueError("n outside 1..max_size")

    def stimulus(rng, count):
        rand = {k: rng.integers(0, n, count) for k in "xyz"}
        edge = sorted({0, 1, cfg.modules - 1, cfg.modules, n - 2, n - 1} & set(range(n)))
        combos = np.array(list(itertools.product(edge, repeat=3)))
        extremes = {"x": combos[:, 0], "y": combos[:, 1], "z": combos[:, 2]}
        return _concat(rand, extremes)

    def model(v):
        x, y, z, p = v["x"], v["y"], v["z"], cfg.modules
        vm, vb, va = skew_model.vp500_miniblock(x, y, z, n, cfg.modules, cfg.banks)
        return {
            "module": skew_model.cube4_module(x, y, z, p),
            "address": skew_model.cube4_address(x, y, z, n, p),
            "vp_module": vm,
            "vp_bank": vb,
            "vp_address": va,
        }

    return _unit_case(
        "skew", lambda: skew.Skew(cfg), skew_model, skew, (cfg,), stimulus, model, statics={"n": n}
    )


# ----------------------------------------------------------------------------- interp


def interp_case(cfg=None, voxel_bits: int = 12, signed_input: bool = False) -> UnitCase:
    cfg = cfg or interp_model.InterpConfig()
    one = 1 << cfg.weight_bits
    # Unsigned voxels 0 .. 2**B - 1, or signed (voxel differences) -2**(B-1) .. 2**(B-1) - 1.
    bottom = -(1 << (voxel_bits - 1)) if signed_input else 0
    top = (1 << (voxel_bits - 1)) - 1 if signed_input else (1 << voxel_bits) - 1

    def stimulus(rng, count):
        rand = {
            "voxels": rng.integers(bottom, top + 1, (count, 8)),
            "frac": rng.integers(0, one + 1, (count, 3)),
        }
        patterns = [
            np.zeros(8),
            np.full(8, top),
            np.full(8, bottom),
            np.tile([bottom, top], 4),
            np.tile([top, bottom], 4),
            np.eye(8)[0] * top,
            np.eye(8)[7] * top,
        ]
        fracs = sorted({0, 1, one // 2, one - 1, one})
        combos = [(p, f) for p in patterns for f in itertools.product(fracs, repeat=3)]
        extremes = {
            "voxels": np.array([p for p, _ in combos], dtype=np.int64),
            "frac": np.array([f for _, f in combos], dtype=np.int64),
        }
        return _concat(rand, extremes)

    def model(v):
        n = v["voxels"].shape[0]
        flat = v["voxels"].ravel()  # vector j's corner c sits at 8 j + c
        idx = (np.arange(n)[None, :] * 8 + np.arange(8)[:, None]).astype(np.int64)
        taps = interp_model.InterpTaps(idx, v["frac"].T)
        return {"sample": interp_model.interpolate(flat, taps, cfg)}

    return _unit_case(
        "interp",
        lambda: interp.Interp(cfg, voxel_bits, signed_input),
        interp_model,
        interp,
        (cfg, voxel_bits, signed_input),
        stimulus,
        model,
    )


def slice_interp_case(cfg=None, voxel_bits: int = 12) -> UnitCase:
    """The top's slice interpolator against ``models.units.interp``'s ``bilinear`` (the
    three samples) and ``lerp`` (the current slice's row and column lerps)."""
    cfg = cfg or interp_model.InterpConfig()
    one = 1 << cfg.weight_bits
    top = (1 << voxel_bits) - 1

    def stimulus(rng, count):
        rand = {
            "corners": rng.integers(0, top + 1, (count, 12)),
            "wa": rng.integers(0, one + 1, count),
            "wb": rng.integers(0, one + 1, count),
        }
        patterns = [np.zeros(12), np.full(12, top), np.tile([0, top], 6), np.tile([top, 0], 6)]
        fracs = sorted({0, 1, one // 2, one - 1, one})
        combos = [(p, fa, fb) for p in patterns for fa in fracs for fb in fracs]
        extremes = {
            "corners": np.array([p for p, _, _ in combos], dtype=np.int64),
            "wa": np.array([fa for _, fa, _ in combos], dtype=np.int64),
            "wb": np.array([fb for _, _, fb in combos], dtype=np.int64),
        }
        return _concat(rand, extremes)

    def model(v):
        c = v["corners"] << cfg.sample_frac_bits
        wa, wb = v["wa"], v["wb"]
        samples = [
            interp_model.bilinear(
                c[:, 4 * s], c[:, 4 * s + 1], c[:, 4 * s + 2], c[:, 4 * s + 3], wa, wb, cfg
            )
            for s in range(3)
        ]
        rows = [interp_model.lerp(c[:, 4 + 2 * i], c[:, 5 + 2 * i], wb, cfg) for i in range(2)]
        cols = [interp_model.lerp(c[:, 4 + j], c[:, 6 + j], wa, cfg) for j in range(2)]
        return {
            "sample": np.stack(samples, axis=1),
            "row": np.stack(rows, axis=1),
            "col": np.stack(cols, axis=1),
        }

    return _unit_case(
        "slice_interp",
        lambda: slice_interp.SliceInterp(cfg, voxel_bits),
        slice_interp,
        slice_interp,
        (cfg, voxel_bits),
        stimulus,
        model,
    )


# --------------------------------------------------------------------------- gradient


def gradient_case(cfg=None, sample_bits: int = 16, spacing_zyx=(1.0, 0.7, 1.3)) -> UnitCase:
    cfg = cfg or gradient_model.GradientConfig()
    top = (1 << sample_bits) - 1
    # The host constants are the model's own: to_world of 4096 along each axis.
    ratio = gradient_model.to_world(np.eye(3, dtype=np.int64) << 12, spacing_zyx, 0, cfg)
    ratio = np.diag(ratio)

    def stimulus(rng, count):
        third = count // 3
        behind = rng.integers(0, top + 1, (count, 3))
        spread = np.concatenate(
            [np.full(third, top + 1), np.full(third, 1024), np.full(count - 2 * third, 16)]
        )[:, None]
        delta = (rng.random((count, 3)) * 2 - 1) * spread
        ahead = np.clip(behind + delta.astype(np.int64), 0, top)
        rand = {"ahead": ahead, "behind": behind}
        rows = []
        for d in itertools.product((-top, -1, 0, 1, top), repeat=3):
            d = np.array(d)
            rows.append((np.where(d > 0, d, 0), np.where(d < 0, -d, 0)))
        rows.append((np.full(3, top), np.full(3, top)))
        extremes = {
            "ahead": np.array([a for a, _ in rows]),
            "behind": np.array([b for _, b in rows]),
        }
        both = _concat(rand, extremes)
        if cfg.source == "sample":
            return both
        # Interpolated voxel differences: central (v[i+1] - v[i-1]) or one-sided at an
        # edge (2 (v[1] - v[0])), so up to twice a sample difference.
        diff = both["ahead"] - both["behind"]
        doubled = np.arange(diff.shape[0]) % 2 == 1
        diff[doubled] *= 2
        return {"diff": diff}

    def model(v):
        g = v["ahead"] - v["behind"] if cfg.source == "sample" else v["diff"]
        g = gradient_model.to_world(g, spacing_zyx, 0, cfg)
        return {"normal": gradient_model.normals(g, cfg), "magnitude": gradient_model.magnitude(g)}

    statics = {"ratio": sum(int(r) << (13 * k) for k, r in enumerate(ratio))}
    return _unit_case(
        "gradient",
        lambda: gradient.Gradient(cfg, sample_bits),
        gradient_model,
        gradient,
        (cfg, sample_bits),
        stimulus,
        model,
        statics=statics,
    )


# --------------------------------------------------------------------------- classify


def classify_case(
    cfg=None, voxel_bits: int = 12, sample_frac_bits: int = 4, modulate: bool = True, seed: int = 7
) -> UnitCase:
    cfg = cfg or classify_model.ClassifyConfig()
    rng = np.random.default_rng(seed)
    cmax, amax = (1 << cfg.color_bits) - 1, (1 << cfg.alpha_bits) - 1
    rgb = rng.integers(0, cmax + 1, (cfg.entries, 3))
    alpha = rng.integers(0, amax + 1, cfg.entries)
    rgb[0], alpha[0], rgb[-1], alpha[-1] = 0, 0, cmax, amax  # black/clear and white/opaque ends
    lut = classify_model.Lut(
        rgb,
        alpha,
        classify_model.expand(rgb, cfg.color_bits),
        classify_model.expand(alpha, cfg.alpha_bits),
    )
    table = rng.integers(0, 4097, cfg.gm_entries)
    table[0], table[-1] = 4096, 0
    scale = classify_model.gm_scale(1.0, 3000.0, cfg)
    sample_bits = voxel_bits + sample_frac_bits
    top = (1 << sample_bits) - 1
    mag_top = (1 << (sample_bits + 3)) - 1
    c = cfg.color_bits
    ll = classify.load_layout(cfg)
    loads = pack(
        ll,
        {
            "table": np.zeros(cfg.entries, np.int64),
            "addr": np.arange(cfg.entries),
            "data": rgb[:, 0] | rgb[:, 1] << c | rgb[:, 2] << 2 * c | alpha << 3 * c,
        },
    )
    loads += pack(
        ll,
        {
            "table": np.ones(cfg.gm_entries, np.int64),
            "addr": np.arange(cfg.gm_entries),
            "data": table,
        },
    )

    def stimulus(rng, count):
        rand = {
            "sample": rng.integers(0, top + 1, count),
            "magnitude": rng.integers(0, 4000, count),
        }
        step = 1 << max(sample_bits - (cfg.entries.bit_length() - 1), 0)
        samples = [
            0,
            1,
            top,
            top - 1,
            step // 2 - 1,
            step // 2,
            step // 2 + 1,
            step * 7 + step // 2,
        ]
        mags = [0, 1, 3000, 2976, 2977, 4000, mag_top]
        combos = np.array(list(itertools.product(samples, mags)))
        return _concat(rand, {"sample": combos[:, 0], "magnitude": combos[:, 1]})

    def model(v):
        rgb12, alpha12 = classify_model.classify(
            v["sample"], lut, voxel_bits, sample_frac_bits, cfg
        )
        if modulate:
            alpha12 = classify_model.modulate(
                alpha12, classify_model.gm_index(v["magnitude"], scale, cfg), table
            )
        return {"rgb": rgb12, "alpha": alpha12}

    return _unit_case(
        "classify",
        lambda: classify.Classify(cfg, voxel_bits, sample_frac_bits),
        classify_model,
        classify,
        (sample_bits,),
        stimulus,
        model,
        out_args=(),
        statics={"gm_scale": scale, "modulate": int(modulate)},
        load_layout=ll,
        loads=loads,
    )


# ------------------------------------------------------------------------------ shade


def shade_case(cfg=None, lights: int = 2) -> UnitCase:
    cfg = cfg or shade_model.ShadeConfig(method="reflectance-map", map_size=16)
    f = cfg.normal_frac_bits
    directions = [np.array([0.3, 0.5, -0.8]), np.array([-0.6, 0.2, -0.77]), np.array([0, 0, -1.0])]
    light_list = [(directions[k % 3], 1.0 - 0.3 * k) for k in range(lights)]
    sh = shade_model.setup(light_list, np.array([0.0, 0.0, -1.0]), (0.15, 0.8, 0.5, 20.0), cfg)
    ll = shade.load_layout(cfg)
    statics = {"ka": sh.ka}
    if cfg.method == "reflectance-map":
        diffuse, specular = sh.maps
        if max(diffuse.max(), specular.max()) >= 1 << shade.MAP_BITS:
            raise ValueError("map entry wider than MAP_BITS")
        k = diffuse.size
        loads = pack(ll, {"table": np.zeros(k, np.int64), "addr": np.arange(k), "data": diffuse})
        loads += pack(ll, {"table": np.ones(k, np.int64), "addr": np.arange(k), "data": specular})
    else:
        k = sh.spec.size
        loads = pack(ll, {"table": np.zeros(k, np.int64), "addr": np.arange(k), "data": sh.spec})
        vbits = f + 2

        def vectors(v):
            return sum(
                (int(c) & ((1 << vbits) - 1)) << (vbits * i) for i, c in enumerate(v.ravel())
            )

        statics.update(
            {
                "light": vectors(sh.light),
                "half": vectors(sh.half),
                "intensity": sum(int(x) << (12 * i) for i, x in enumerate(sh.intensity)),
                "kd": sh.kd,
                "ks": sh.ks,
            }
        )
    one_n = 1 << f

    def stimulus(rng, count):
        half = count // 2
        unit = rng.normal(size=(half, 3))
        unit = np.floor(unit / np.linalg.norm(unit, axis=1, keepdims=True) * one_n + 0.5)
        anywhere = rng.integers(-one_n, one_n + 1, (count - half, 3))
        rand = {
            "rgb": rng.integers(0, 4097, (count, 3)),
            "normal": np.concatenate([unit.astype(np.int64), anywhere]),
        }
        normals = [(0, 0, 0)]
        for axis, sign in itertools.product(range(3), (1, -1)):
            e = [0, 0, 0]
            e[axis] = sign * one_n
            normals.append(tuple(e))
        normals += [
            (one_n, one_n, 0),
            (0, -one_n, one_n),
            (one_n, one_n, one_n),
            (-one_n, -one_n, -one_n),
            (1, 0, 0),
            (0, 0, -1),
            (1, -1, 1),
            (one_n, -one_n, one_n - 1),
            (one_n - 1, one_n, -one_n),
        ]
        colours = [(0, 0, 0), (4096, 4096, 4096), (4096, 0, 2048)]
        combos = list(itertools.product(colours, normals))
        extremes = {
            "rgb": np.array([c for c, _ in combos]),
            "normal": np.array([n for _, n in combos]),
        }
        return _concat(rand, extremes)

    def model(v):
        return {"rgb": shade_model.shade(sh, v["rgb"], v["normal"])}

    return _unit_case(
        "shade",
        lambda: shade.Shade(cfg, lights),
        shade_model,
        shade,
        (cfg,),
        stimulus,
        model,
        out_args=(),
        statics=statics,
        load_layout=ll,
        loads=loads,
    )


# -------------------------------------------------------------------------- composite


def composite_case(
    cfg=None, sample_bits: int = 16, k: float = 1.7, threshold: float = 0.95
) -> UnitCase:
    cfg = cfg or composite_model.CompositeConfig()
    one = 1 << cfg.acc_frac_bits
    kq = int(cfg.ratio.quantize(k))
    table = composite_model.correction_table(kq, cfg)
    ll = composite.load_layout()
    loads = pack(ll, {"addr": np.arange(table.size), "data": table})
    enable = threshold < 1.0
    thr = int(cfg.acc.quantize(max(min(threshold, 1.0), 0.0)))
    top = (1 << sample_bits) - 1

    def stimulus(rng, count):
        a_acc = rng.integers(0, one + 1, count)
        rand = {
            "acc": np.concatenate([rng.integers(0, one + 1, (count, 3)), a_acc[:, None]], axis=1),
            "rgb": rng.integers(0, 4097, (count, 3)),
            "alpha": rng.integers(0, 4097, count),
            "mip": rng.integers(0, top + 1, count),
            "sample": rng.integers(0, top + 1, count),
        }
        accs = [0, 1, thr - 1, thr, one - 1, one]
        alphas = [0, 1, 2047, 2048, 4095, 4096, 4097, 8191]
        colours = [0, 4096, 8191]
        rows = list(itertools.product(accs, alphas, colours))
        extremes = {
            "acc": np.array([[a, a, a, a] for a, _, _ in rows]),
            "rgb": np.array([[c, c, 0] for _, _, c in rows]),
            "alpha": np.array([al for _, al, _ in rows]),
            "mip": np.array([top if i % 2 else 0 for i in range(len(rows))]),
            "sample": np.array([0 if i % 3 else top for i in range(len(rows))]),
        }
        return _concat(rand, extremes)

    @_keep_saturation_log
    def model(v):
        n = v["alpha"].size
        acc = v["acc"].copy()
        rays = np.arange(n)
        corrected = composite_model.correct_opacity(
            v["alpha"], kq / (1 << cfg.ratio_frac_bits), cfg
        )
        composite_model.front_to_back(acc, rays, v["rgb"], corrected, cfg)
        term = composite_model.terminated(acc, threshold, cfg)
        mip = v["mip"].copy()
        composite_model.mip(mip, rays, v["sample"])
        return {"acc": acc, "mip": mip, "terminated": term.astype(np.int64)}

    statics = {"ert_threshold": thr if enable else 0, "ert_enable": int(enable)}
    return _unit_case(
        "composite",
        lambda: composite.Composite(cfg, sample_bits),
        composite_model,
        composite,
        (cfg, sample_bits),
        stimulus,
        model,
        statics=statics,
        load_layout=ll,
        loads=loads,
    )


_FACTORIES = {
    "skew": skew_case,
    "interp": interp_case,
    "slice_interp": slice_interp_case,
    "gradient": gradient_case,
    "classify": classify_case,
    "shade": shade_case,
    "shade_phong": lambda **o: shade_case(cfg=shade_model.ShadeConfig(method="phong"), **o),
    "composite": composite_case,
}


def make_case(unit: str, **options) -> UnitCase:
    """The case of ``unit`` (one of :data:`UNITS` or :data:`COSIM_CASES`) with its default
    or given options."""
    return _FACTORIES[unit](**options)
