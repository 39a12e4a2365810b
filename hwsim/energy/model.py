"""Energy per frame and silicon area of one rendered frame: action counts times prices.

# Ref: docs/energy.md (every rule and assumption); models/units/ops.py (what each unit
#      does per sample); models/machines/<family>/silicon.py (each machine's buffers and
#      memory actions); hwsim/energy/technology.py (the prices).

Dynamic energy is the frame's actions priced by the technology:

* a datapath unit acts once per sample it processes (the cycle rung's per-pipeline
  ``inputs`` counters; the transaction rung's ``frame.samples``); elided units perform
  no actions; one action costs the unit's operator inventory at its widths;
* each memory action of the family's :func:`accesses`: SDRAM reads per bit,
  activations and refreshes per command, on-chip buffers per access by array size.

Static energy is the machine's area times the technology's leakage density times the
frame time.  Area is the machine's silicon whatever the scene: every datapath unit of
every pipeline (its operators instantiated once each, its pipeline registers and tables)
plus the buffers, sized for the machine's largest volume.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from hwsim.energy.fpga import unit_fpga
from hwsim.energy.synth import INDEPENDENCE, synthesised, unit_datapath, unit_silicon
from hwsim.energy.technology import Technology
from models.machines.common.silicon import Silicon, counter_sum
from models.units.ops import SHARED, Features, Op, unit_ops

__all__ = [
    "DATAPATH",
    "RTL_FEATURES",
    "arch_features",
    "estimate",
    "machine_area",
    "machine_units",
    "op_area_um2",
    "op_energy_pj",
    "rtl_kind_differs",
    "rtl_width_inventory",
    "split_area",
    "synthesized_unit",
    "unit_inventory",
    "unit_joules_per_sample",
]

#: The datapath units priced (the crop unit only where the machine has one).
DATAPATH = ("interp", "gradient", "classify", "shade", "composite", "crop")
_PJ, _UM2_PER_MM2 = 1e-12, 1e6
#: The frame's samples the hardware issued (VIZARD II's transaction rung names them so).
_SAMPLES = ("frame.issued_samples", "frame.samples")


def op_energy_pj(op: Op, tech: Technology) -> float:
    """One sample's worth of ``op``: ``count`` operations."""
    if op.kind == "add":
        each = tech.add_pj(op.a)
    elif op.kind == "mult":
        each = tech.mult_pj(op.a, op.b)
    elif op.kind == "table":
        each = tech.sram_pj(op.a, op.a * op.b)
    else:  # register
        each = tech.register_pj(op.a)
    return each * op.count


def op_area_um2(op: Op, tech: Technology) -> float:
    """The hardware of ``op`` in one pipeline (its ``instances``)."""
    if op.kind == "add":
        return tech.add_um2(op.a) * op.instances
    if op.kind == "mult":
        return tech.mult_um2(op.a, op.b) * op.instances
    if op.kind == "table":
        return tech.storage_um2(op.a * op.b) * op.instances
    return tech.storage_um2(int(op.a * op.instances))  # registers: flip-flops


def unit_inventory(
    unit: str, dp, silicon: Silicon, lights: int, shading: str, features: Features = SHARED
) -> list[Op]:
    """``unit``'s operators per sample on datapath ``dp`` (``features``: the machine's
    hardware beyond the shared datapath, :func:`arch_features`)."""
    return unit_ops(
        unit,
        voxel_bits=dp.voxel_bits,
        sample_frac_bits=dp.interp.sample_frac_bits,
        weight_bits=dp.interp.weight_bits,
        lerps=silicon.lerps,
        gradient_source=dp.gradient.source,
        normal_frac_bits=dp.gradient.normal_frac_bits,
        lut_entries=dp.classify.entries,
        color_bits=dp.classify.color_bits,
        alpha_bits=dp.classify.alpha_bits,
        lights=lights,
        shading=shading,
        spec_table_entries=dp.shade.spec_table_entries,
        map_size=dp.shade.map_size,
        acc_frac_bits=dp.composite.acc_frac_bits,
        gm_entries=dp.classify.gm_entries,
        xray_frac_bits=dp.composite.xray_frac_bits,
        xray_acc_bits=dp.composite.xray_acc_bits,
        features=features,
    )


def arch_features(arch, scene=None) -> Features:
    """What ``arch``'s datapath holds beyond the shared one, from its ``[features]``: its
    other compositing modes and blend orders, early termination, gradient-magnitude
    illumination, cut planes; with ``scene``, the blend its samples use and its planes
    (the operators of the others are built but do not act)."""
    blends = {m for m in arch.modes if m != "composite"}
    blends |= {b for b in arch.blend_orders if b != "front-to-back"}
    used: dict[str, Any] = {}
    if scene is not None:
        mode = scene.render.mode
        blend = scene.render.blend_order if mode == "composite" else mode
        blends.add(blend)  # a what-if extension performs what the frame asks
        blends.discard("front-to-back")
        used = {"blend": blend, "planes_used": len(scene.cut_planes)}
    return Features(
        blends=frozenset(blends),
        early_termination=arch.early_termination,
        gradient_illumination=arch.gradient_illumination,
        cut_planes=arch.cut_planes,
        **used,
    )


#: What the synthesised RTL builds beyond the shared datapath (rtl/*.py module docs): the
#: compositor's MIP and early-termination compare (rtl/composite.py); no illumination
#: modulation (rtl/classify.py, rtl/shade.py); no crop unit.
RTL_FEATURES = Features(blends=frozenset({"mip"}), early_termination=True)


def _unit_actions(counters: Mapping[str, int], unit: str) -> int:
    """Samples ``unit`` processed: its pipelines' ``inputs`` (cycle rung), else the frame's
    samples (transaction rung: every issued sample passes every elaborated unit)."""
    return counter_sum(counters, f"pipeline[].{unit}.inputs", *_SAMPLES)


def rtl_width_inventory(unit: str, silicon: Silicon, params: dict[str, Any]) -> list[Op]:
    """``unit``'s operator inventory at the synthesised RTL's widths ``params`` (its
    default widths; the RTL's interp unit is trilinear, the shader has one light) and
    with the features it builds (:data:`RTL_FEATURES`)."""
    same = dataclasses.replace(silicon, lerps=7)
    return unit_inventory(
        unit, unit_datapath(unit, params), same, params.get("lights", 1),
        params.get("method", "phong"), RTL_FEATURES,
    )  # fmt: skip


def split_area(inventory: list[Op], tech: Technology) -> dict[str, float]:
    """The table's area of ``inventory`` split as the two ways compare it: ``logic_mm2``
    (operators and pipeline registers), ``storage_mm2`` and ``storage_bits`` (its tables:
    LUTs, ROMs, maps)."""
    tables = [op for op in inventory if op.kind == "table"]
    logic = sum(op_area_um2(op, tech) for op in inventory if op.kind != "table")
    return {
        "logic_mm2": logic / _UM2_PER_MM2,
        "storage_mm2": sum(op_area_um2(op, tech) for op in tables) / _UM2_PER_MM2,
        "storage_bits": sum(int(op.a * op.b * op.instances) for op in tables),
    }


def synthesized_unit(unit: str, silicon: Silicon, tech: Technology, arch) -> dict[str, Any] | None:
    """``unit``'s RTL as synthesised (:mod:`hwsim.energy.synth`, one pipeline's unit at
    its default widths), with the table's area of the same unit at the same widths beside
    it, and whether its longest path meets ``arch``'s clock (an estimate).

    Logic and storage are kept apart: only the logic is priced independently on the two
    sides (operator table from the unit models vs Yosys cells of the RTL); storage is
    counted in bits on each side but priced by the same :meth:`Technology.storage_um2`, so
    its agreement is by construction (``independence``).  ``logic_table_over_synthesized``
    is the comparison that tests the table; ``table_over_synthesized`` (totals) mostly
    repeats the shared SRAM price where tables dominate."""
    syn = unit_silicon(unit, tech, arch.clock_hz)
    if syn is None:
        return None
    inventory = rtl_width_inventory(unit, silicon, syn["params"])
    table = sum(op_area_um2(op, tech) for op in inventory) / _UM2_PER_MM2
    split = split_area(inventory, tech)
    return {
        **syn,
        "table_mm2_same_widths": table,
        "table_over_synthesized": table / syn["mm2"],
        "table_logic_mm2": split["logic_mm2"],
        "table_storage_mm2": split["storage_mm2"],
        "table_storage_bits": split["storage_bits"],
        "logic_table_over_synthesized": split["logic_mm2"] / syn["logic_mm2"],
        "independence": INDEPENDENCE,
    }


def rtl_kind_differs(unit: str, dp) -> str | None:
    """Why the synthesised RTL of ``unit`` is not the unit datapath ``dp`` has, or None.

    Widths may differ (the RTL is synthesised at its default widths and the table is
    priced at the same ones); a choice of kind may not: the RTL's ``shade.method``
    (``reflectance-map``) against a Phong machine, or its ``gradient.source``
    (``sample``) against a machine that takes gradients at the voxels, is another unit,
    and comparing its area with the table's says nothing about this machine."""
    entry = synthesised()["units"].get(unit)
    cfg = getattr(dp, unit, None)
    if entry is None or cfg is None:
        return None
    differ = [
        f"{unit}.{key} {getattr(cfg, key)} here, {value} in the RTL"
        for key, value in sorted(entry["params"].items())
        if isinstance(value, str) and hasattr(cfg, key) and getattr(cfg, key) != value
    ]
    return "; ".join(differ) or None


def machine_area(arch, dp, tech: Technology) -> dict[str, Any]:
    """The silicon of ``arch`` with datapath ``dp``, whatever the scene: every pipeline's
    units (one light's hardware each) and the buffers."""
    from models.machines import machine_for

    silicon = machine_for(arch).silicon(arch, dp)
    P = arch.pipelines
    unit_area = {}
    features = arch_features(arch)
    for u in machine_units(arch):
        inventory = unit_inventory(u, dp, silicon, 1, dp.shade.method, features)
        per = sum(op_area_um2(op, tech) for op in inventory)
        other = rtl_kind_differs(u, dp)
        unit_area[u] = {
            "mm2": P * per / _UM2_PER_MM2,
            "per_pipeline_mm2": per / _UM2_PER_MM2,
            "gate_equivalents": P * per / tech.gate_um2(1.0),
            # Area two ways only where the RTL is this machine's kind of unit.
            "synthesized": None if other else synthesized_unit(u, silicon, tech, arch),
            # The third way: the same RTL placed and routed on an ECP5 (hwsim.energy.fpga).
            "fpga": None if other else unit_fpga(u, arch.clock_hz),
            "rtl_differs": other,
        }
    buffers = {
        s.name: {
            "mm2": s.copies * tech.storage_um2(s.bits) / _UM2_PER_MM2,
            "gate_equivalents": s.copies * tech.storage_um2(s.bits) / tech.gate_um2(1.0),
            "bits": s.copies * s.bits,
            "copies": s.copies,
        }
        for s in silicon.storage
    }
    total = sum(a["mm2"] for a in unit_area.values()) + sum(b["mm2"] for b in buffers.values())
    return {
        "total_mm2": total,
        "gate_equivalents": total * _UM2_PER_MM2 / tech.gate_um2(1.0),
        "pipelines": P,
        "per_pipeline_mm2": sum(a["per_pipeline_mm2"] for a in unit_area.values()),
        "units": unit_area,
        "buffers": buffers,
    }


def unit_joules_per_sample(arch, dp, scene, units: list[str], tech: Technology) -> dict[str, float]:
    """Energy of one action of each of ``units`` (those of ``arch``'s datapath) for
    ``scene`` (its lights) on datapath ``dp``."""
    from models.machines import machine_for

    silicon = machine_for(arch).silicon(arch, dp)
    lights = max(1, len(scene.lights)) if scene.lit else 0
    features = arch_features(arch, scene)
    out = {}
    for u in (u for u in machine_units(arch) if u in units):
        inventory = unit_inventory(u, dp, silicon, lights, dp.shade.method, features)
        out[u] = sum(op_energy_pj(op, tech) for op in inventory) * _PJ
    return out


def machine_units(arch) -> list[str]:
    """The datapath units ``arch`` has (the crop unit only where it crops)."""
    return [u for u in DATAPATH if u != "crop" or arch.crop]


def estimate(
    *,
    arch,
    dp,
    scene,
    counters: Mapping[str, int],
    units: list[str],
    cycles: int | None,
    tech: Technology,
) -> dict[str, Any]:
    """``{"technology", "energy", "area"}`` of one frame (``units``: the elaborated ones)."""
    from models.machines import machine_for

    family = machine_for(arch)
    silicon = family.silicon(arch, dp)
    area = machine_area(arch, dp, tech)
    unit_energy = {}
    for u, per in unit_joules_per_sample(arch, dp, scene, units, tech).items():
        actions = _unit_actions(counters, u)
        unit_energy[u] = {"actions": actions, "joules_per_action": per, "joules": actions * per}
    storage = {s.name: s for s in silicon.storage}
    memories: dict[str, dict[str, Any]] = {}
    for acc in family.accesses(counters, arch, dp, units):
        if acc.store == "dram":
            price = {
                "read": acc.word_bits * tech.v("energy", "dram_read_bit_pj"),
                "activate": tech.v("energy", "dram_activate_pj"),
                "refresh": tech.v("energy", "dram_refresh_pj"),
            }[acc.kind]
        else:
            price = tech.sram_pj(acc.word_bits, storage[acc.store].bits)
        entry = memories.setdefault(acc.store, {"joules": 0.0, "actions": {}})
        entry["actions"][acc.kind] = entry["actions"].get(acc.kind, 0) + acc.count
        entry["joules"] += acc.count * price * _PJ
    dynamic = sum(e["joules"] for e in unit_energy.values()) + sum(
        m["joules"] for m in memories.values()
    )
    frame_seconds = cycles / arch.clock_hz if cycles else None
    static = area["total_mm2"] * tech.leakage_w_per_mm2 * frame_seconds if frame_seconds else 0.0
    total = dynamic + static
    samples = counter_sum(counters, *_SAMPLES)
    return {
        "technology": tech.describe(),
        "energy": {
            "total_joules": total,
            "dynamic_joules": dynamic,
            "static_joules": static,
            "per_sample_joules": total / samples if samples else None,
            "average_watts": total / frame_seconds if frame_seconds else None,
            "frame_seconds": frame_seconds,
            "units": unit_energy,
            "memories": memories,
        },
        "area": area,
    }
