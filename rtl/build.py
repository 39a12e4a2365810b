"""``hwsim rtl build``: Verilog of the units and their synthesis statistics.

The Verilog comes from Amaranth's built-in Yosys (:func:`rtl.export.to_verilog`).  The
cell counts come from a full Yosys on PATH (Debian's ``yosys``, installed by ``./dev
test``): Amaranth's built-in build has no ``synth``, ``techmap``, ``abc`` or ``stat``.
The flow is generic (no vendor library): ``proc; flatten; opt; wreduce; memory -nomap;
opt -full; techmap; opt`` (optionally ``abc -fast`` to two-input gates and
multiplexers), then ``stat -json``.  SRAMs stay as memory cells; their bits are reported
separately.

Widths are set per unit with ``--set UNIT.KEY=VALUE`` (the unit's ``models.units``
config fields plus ``voxel_bits`` / ``sample_bits``), so the bit-width trade can be
priced in gates.
"""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

from hwsim.core.errors import HwsimError, InputError
from hwsim.core.paths import write_text_atomic

__all__ = ["UNITS", "TARGETS", "parse_settings", "build_unit", "synthesize", "build"]

UNITS = ("skew", "interp", "gradient", "classify", "shade", "composite")
#: What ``hwsim rtl build`` accepts: the units (``all``) and the Cube-4 pipeline top.
TARGETS = (*UNITS, "top")


def _registry() -> dict[str, tuple[type, dict, Callable]]:
    """unit -> (config class, extra parameters with defaults, factory(cfg, **extra))."""
    from models.units.classify import ClassifyConfig
    from models.units.composite import CompositeConfig
    from models.units.gradient import GradientConfig
    from models.units.interp import InterpConfig
    from models.units.shade import ShadeConfig
    from models.units.skew import SkewConfig
    from rtl import classify, composite, gradient, interp, shade, skew, top

    return {
        "top": (top.TopConfig, {}, lambda cfg: cfg.build()),
        "skew": (SkewConfig, {}, lambda cfg: skew.Skew(cfg)),
        "interp": (
            InterpConfig,
            {"voxel_bits": 12},
            lambda cfg, voxel_bits: interp.Interp(cfg, voxel_bits),
        ),
        "gradient": (
            GradientConfig,
            {"sample_bits": 16},
            lambda cfg, sample_bits: gradient.Gradient(cfg, sample_bits),
        ),
        "classify": (
            ClassifyConfig,
            {"voxel_bits": 12, "sample_frac_bits": 4},
            lambda cfg, voxel_bits, sample_frac_bits: classify.Classify(
                cfg, voxel_bits, sample_frac_bits
            ),
        ),
        "shade": (ShadeConfig, {"lights": 1}, lambda cfg, lights: shade.Shade(cfg, lights)),
        "composite": (
            CompositeConfig,
            {"sample_bits": 16},
            lambda cfg, sample_bits: composite.Composite(cfg, sample_bits),
        ),
    }


_EXTRA_RANGES = {
    "voxel_bits": (1, 16),
    "sample_bits": (2, 30),
    "sample_frac_bits": (0, 12),
    "lights": (1, 8),
}


def parse_settings(items: list[str]) -> dict[str, dict[str, int | str]]:
    """``["interp.weight_bits=6", ...]`` -> ``{"interp": {"weight_bits": 6}}``; unknown
    units, keys or non-integer widths raise :class:`InputError`."""
    registry = _registry()
    out: dict[str, dict[str, int | str]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        unit, dot, name = key.partition(".")
        if not sep or not dot:
            raise InputError(f"expected UNIT.KEY=VALUE, got {item!r}", source="--set")
        if unit not in registry:
            raise InputError("unknown unit", source="--set", key=key, allowed=", ".join(TARGETS))
        cls, extra, _ = registry[unit]
        fields = {f.name: f for f in dataclasses.fields(cls)}
        allowed = sorted([*fields, *extra])
        if name not in allowed:
            raise InputError("unknown key", source="--set", key=key, allowed=", ".join(allowed))
        default = extra[name] if name in extra else fields[name].default
        if isinstance(default, int):
            try:
                value: int | str = int(text)
            except ValueError:
                raise InputError(f"{text!r} is not an integer", source="--set", key=key) from None
            lo, hi = _EXTRA_RANGES.get(name, (None, None))
            if lo is not None and not lo <= value <= hi:
                raise InputError(
                    f"{value} is out of range", source="--set", key=key, allowed=f"{lo} .. {hi}"
                )
        else:
            value = text
        out.setdefault(unit, {})[name] = value
    return out


def build_unit(unit: str, settings: dict[str, int | str] | None = None):
    """Elaborate ``unit`` with ``settings``: ``(component, resolved parameters)``."""
    cls, extra, factory = _registry()[unit]
    settings = dict(settings or {})
    params = {k: settings.pop(k, v) for k, v in extra.items()}
    if unit == "shade":
        settings.setdefault("method", "reflectance-map")  # VolumePro 500's shader
    try:
        cfg = cls(**settings)
        component = factory(cfg, **params)
    except ValueError as exc:
        raise InputError(str(exc), source="--set", key=unit) from None
    resolved = {**dataclasses.asdict(cfg), **params}
    return component, resolved


def _yosys() -> str:
    path = shutil.which("yosys")
    if path is None:
        raise HwsimError(
            "synthesis statistics need a full Yosys on PATH (apt-get install yosys; "
            "Amaranth's built-in Yosys has no synth/stat); use --no-synth for Verilog only"
        )
    return path


_LTP = re.compile(r"Longest topological path in \S+ \(length=(\d+)\)")
_MEMORY = re.compile(r"^\s*reg\s+\[(\d+):0\]\s+\S+\s+\[(\d+):0\];", re.M)
#: A memory's power-up contents (``initial begin mem[i] = ...; end``): the SRAMs are
#: loaded at run time, and Yosys spends minutes on tens of thousands of init words.
MEMORY_INIT = re.compile(
    r"(^\s*reg\s+\[\d+:0\]\s+(\S+)\s+\[\d+:0\];\n)\s*initial begin\n"
    r"(?:\s*\2\[\d+\] = [^;]+;\n)*\s*end\n",
    re.M,
)


def synthesize(verilog: str, top: str, abc: bool = False) -> dict:
    """Generic gate-level synthesis of one module: cell counts by type, total cells,
    flip-flops, SRAM bits (kept as memories) and the longest path between flip-flops in
    gates (Yosys ``ltp -noff``).

    Without ``abc`` the counts are Yosys' own techmap gates after ``opt`` (seconds per
    unit); ``abc`` re-maps them with ABC's fast script (minutes for the gradient unit's
    square root and dividers)."""
    script = (
        f"read_verilog top.v; hierarchy -top {top}; proc; flatten; opt; wreduce; "
        "memory -nomap; opt -full; techmap; opt -fast; "
        + ("abc -fast -g AND,NAND,OR,NOR,XOR,XNOR,ANDNOT,ORNOT,MUX; " if abc else "")
        + "opt_clean; tee -q -o stat.json stat -json; tee -q -o ltp.txt ltp -noff"
    )
    with tempfile.TemporaryDirectory(prefix="hwsim-synth-") as tmp:
        Path(tmp, "top.v").write_text(MEMORY_INIT.sub(r"\1", verilog))
        done = subprocess.run(
            [_yosys(), "-q", "-p", script], cwd=tmp, capture_output=True, text=True, check=False
        )
        if done.returncode != 0:
            raise HwsimError(f"yosys failed on {top}: {done.stderr.strip()[-500:]}")
        stat = json.loads(Path(tmp, "stat.json").read_text())
        ltp = _LTP.search(Path(tmp, "ltp.txt").read_text())
    design = stat["design"]
    by_type = {k: int(v) for k, v in design["num_cells_by_type"].items()}
    memories = [(int(w) + 1) * (int(d) + 1) for w, d in _MEMORY.findall(verilog)]
    return {
        "cells": sum(v for k, v in by_type.items() if not k.startswith("$mem")),
        "flip_flops": sum(v for k, v in by_type.items() if "DFF" in k),
        "cells_by_type": by_type,
        "memories": len(memories),
        "memory_bits": sum(memories),
        # Gates on the longest path between flip-flops (and ports): the logic levels one
        # clock must cover.
        "logic_levels": int(ltp.group(1)) if ltp else None,
    }


def build(
    units: list[str],
    out: Path,
    settings: dict[str, dict],
    synth: bool = True,
    abc: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> dict:
    """Write ``out/<unit>.v`` for each unit and, with ``synth``, ``out/synth.json``
    (schema 1: per unit its resolved parameters, LATENCY, II, ``cells``,
    ``flip_flops``, ``cells_by_type``, ``memories``, ``memory_bits``)."""
    from rtl import classify, composite, gradient, interp, shade, skew, top
    from rtl.export import to_verilog

    modules = {
        "top": top,
        "skew": skew,
        "interp": interp,
        "gradient": gradient,
        "classify": classify,
        "shade": shade,
        "composite": composite,
    }
    out.mkdir(parents=True, exist_ok=True)
    flow = "yosys generic: techmap" + (" + abc -fast to 2-input gates" if abc else " gates")
    report = {"schema": 1, "flow": flow, "units": {}}
    for k, unit in enumerate(units):
        component, params = build_unit(unit, settings.get(unit))
        text = to_verilog(component, unit)
        write_text_atomic(out / f"{unit}.v", text)
        # The top has no one latency: its frame's timing is its structure's (rtl/top.py).
        entry = {
            "params": params,
            "latency": getattr(modules[unit], "LATENCY", None),
            "ii": getattr(modules[unit], "II", None),
            "verilog": f"{unit}.v",
        }
        if synth:
            entry.update(synthesize(text, unit, abc))
        report["units"][unit] = entry
        if progress:
            progress(k + 1, len(units))
    if synth:
        write_text_atomic(out / "synth.json", json.dumps(report, indent=1, sort_keys=True) + "\n")
    return report
