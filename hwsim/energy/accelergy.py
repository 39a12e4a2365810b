"""A frame's actions priced a second way: Accelergy's component library (hwcomponents).

# Ref: docs/energy.md ("Cross-check: Accelergy's component library"); hwcomponents
#      (Andrulis et al., MIT; PyPI hwcomponents, hwcomponents-library, hwcomponents-cacti).

The same action counts the estimate prices (:func:`hwsim.energy.estimate_frame`: each
datapath unit's operator inventory once per sample, each memory access of the family's
``accesses``) are priced by the library's components at the technology's node and the
same widths; nothing of the Horowitz-based tables enters the library's side:

* add (and compare, subtract: the inventory does not tell them apart): ``AladdinAdder``
  (Aladdin, 40 nm, 0.21 pJ at 32 bits, linear in the width);
* multiply: ``AladdinMultiplier`` (12.68 pJ at 32 x 32, linear in each operand's width);
* register bit written: ``AladdinRegister`` (0.009 pJ a bit);
* table read, buffer read or write: ``SRAM`` of hwcomponents-cacti (CACTI 7 at 22-90 nm,
  the word and array size as the estimate has them);
* SDRAM bits read: ``DDR3`` of hwcomponents-cacti, 70 pJ a bit at every node (its oldest
  SDRAM; no PC100). Row activations and refreshes have no action in the library: they are
  reported apart (``not_priced``), outside the band, as is leakage.

The library scales logic from 40 nm by Stillmaker and Baas' tables (130-7 nm, at 0.8 V:
it takes no supply voltage); above 130 nm its energy grows only with the square root of
the node, and its SRAM above 90 nm is CACTI's 22 nm array times the square root of
node / 22 nm.  So at 0.25 and 0.35 um (2.5 V and 3.3 V) it prices a modern low-voltage
process drawn large, not those processes: the band there mostly measures the voltage.

The library needs Python >= 3.12 and runs CACTI as a program, so its prices are stored
(``hwsim/energy/data/accelergy_prices.json``: the logic at 32 bits with the library's own
width rules, every SRAM shape the built-in machines use) and regenerated with
``python -m hwsim.energy.accelergy`` (the ``energy`` extra); a shape not stored is priced
live when the library is installed, else refused naming the extra.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import shutil
import subprocess
import sys
import types
import warnings
from collections.abc import Mapping
from functools import cache
from importlib import metadata, resources
from pathlib import Path
from typing import Any

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.energy.technology import Technology, load_technology

__all__ = [
    "EXTRA",
    "band",
    "band_of_run",
    "library_versions",
    "live_prices",
    "main",
    "stored_prices",
]

#: The pyproject extra that installs the library.
EXTRA = "energy"
PACKAGES = ("hwcomponents", "hwcomponents-library", "hwcomponents-cacti")
#: The library's SDRAM priced for every machine's external memory.
DRAM_TYPE = "DDR3"
#: The nodes stored: every built-in technology's.
NODES = ("cmos45", "cmos250", "cmos350")
_DATA = "accelergy_prices.json"
_PJ = 1e-12
_INSTALL = (
    f"Accelergy's component library is not installed: pip install 'hwsim[{EXTRA}]' "
    "(Python >= 3.12; on 3.11 see docs/energy.md)"
)


def _bare_package(name: str) -> types.ModuleType:
    """``name`` as a package whose ``__init__`` is not run (its submodules import)."""
    spec = importlib.util.find_spec(name)
    if spec is None or spec.submodule_search_locations is None:
        raise ModuleNotFoundError(name)
    pkg = types.ModuleType(name)
    pkg.__path__ = list(spec.submodule_search_locations)
    pkg.__spec__ = spec
    sys.modules[name] = pkg
    return pkg


@cache
def _library() -> types.SimpleNamespace:
    """The library's components, or :class:`NotAvailableError` naming the extra.

    On Python 3.11 (installed with ``--ignore-requires-python``) ``hwcomponents``'
    ``__init__`` fails on one Python 3.12 f-string in ``select_models`` (model selection
    by name, unused here): the package is then entered without it.  The components come
    from their modules, ``hwcomponents_library``'s ``__init__`` not run: it imports every
    model set it holds, one of them from hwcomponents-neurosim (35 MB, undeclared)."""
    try:
        try:
            import hwcomponents  # noqa: F401
        except SyntaxError:
            for key in [k for k in sys.modules if k.split(".")[0] == "hwcomponents"]:
                del sys.modules[key]
            pkg = _bare_package("hwcomponents")
            model = importlib.import_module("hwcomponents.model")
            pkg.ComponentModel, pkg.action = model.ComponentModel, model.action
            pkg.ActionCost = model.ActionCost
            pkg.scaling = importlib.import_module("hwcomponents.scaling")
        if "hwcomponents_library" not in sys.modules:
            _bare_package("hwcomponents_library")
        aladdin = importlib.import_module("hwcomponents_library.library.aladdin")
        cacti = importlib.import_module("hwcomponents_cacti.hwcomponents_cacti")
    except ImportError:
        raise NotAvailableError(_INSTALL) from None
    return types.SimpleNamespace(aladdin=aladdin, cacti=cacti)


def library_versions() -> dict[str, str]:
    """The installed library's packages and versions."""
    return {p: metadata.version(p) for p in PACKAGES}


def live_prices(node_nm: float, srams: list[tuple[int, int]] = ()) -> dict[str, Any]:
    """The library's prices at ``node_nm`` (pJ): logic at 32 bits, a register bit, an
    SDRAM bit read, and each ``(word_bits, array_bits)`` SRAM's read and write."""
    # hwcomponents-cacti reads its CACTI template through a file it never closes.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        return _live_prices(_library(), node_nm, srams)


def _live_prices(lib, node_nm: float, srams) -> dict[str, Any]:
    node, al = node_nm * 1e-9, lib.aladdin
    out: dict[str, Any] = {
        "node_nm": node_nm,
        "add_32b_pj": al.AladdinAdder(tech_node=node, width=32).add().energy / _PJ,
        "mult_32x32_pj": al.AladdinMultiplier(tech_node=node, width_a=32, width_b=32)
        .multiply()
        .energy
        / _PJ,
        "register_bit_pj": al.AladdinRegister(tech_node=node, width=1).write().energy / _PJ,
        "dram_read_bit_pj": getattr(lib.cacti, DRAM_TYPE)(width=64).read().energy / 64 / _PJ,
        "sram": {},
    }
    for word, bits in srams:
        s = lib.cacti.SRAM(tech_node=node, width=word, size=bits)
        out["sram"][f"{word}/{bits}"] = [s.read().energy / _PJ, s.write().energy / _PJ]
    return out


@cache
def stored_prices() -> dict[str, Any]:
    """The stored table (``hwsim/energy/data/accelergy_prices.json``)."""
    path = resources.files("hwsim.energy") / "data" / _DATA
    return json.loads(path.read_text())


class _Prices:
    """The library's price of each action at one node: stored, else live."""

    def __init__(self, tech: Technology):
        self.node, stored = tech.node_nm, stored_prices()["nodes"]
        self.table = stored.get(_node_key(tech.node_nm))
        if self.table is None:
            try:
                self.table = live_prices(tech.node_nm)
            except NotAvailableError:
                nodes = ", ".join(f"{k} nm" for k in sorted(stored, key=float))
                raise NotAvailableError(
                    f"no stored Accelergy prices at {self.node:g} nm (stored: {nodes}), "
                    f"and {_INSTALL}"
                ) from None

    def sram_pj(self, word: int, bits: int, kind: str) -> float:
        key = f"{word}/{bits}"
        if key not in self.table["sram"]:
            try:
                self.table["sram"].update(live_prices(self.node, [(word, bits)])["sram"])
            except NotAvailableError:
                raise NotAvailableError(
                    f"no stored Accelergy price for a {word}-bit word of a {bits}-bit SRAM "
                    f"at {self.node:g} nm, and {_INSTALL}"
                ) from None
        return self.table["sram"][key][0 if kind == "read" else 1]

    def op_pj(self, op) -> float:
        """One sample's worth of an inventory entry (:class:`models.units.ops.Op`)."""
        t = self.table
        if op.kind == "add":
            each = t["add_32b_pj"] * op.a / 32
        elif op.kind == "mult":
            each = t["mult_32x32_pj"] * (op.a / 32) * (op.b / 32)
        elif op.kind == "table":
            each = self.sram_pj(op.a, op.a * op.b, "read")
        else:  # register: its bits written once
            each = t["register_bit_pj"] * op.a
        return each * op.count


def _node_key(node_nm: float) -> str:
    return f"{node_nm:g}"


def _inventories(arch, dp, scene, units: list[str]) -> dict[str, list]:
    """Each unit's operator inventory as :func:`~hwsim.energy.model.unit_joules_per_sample`
    prices it (the scene's lights, the machine's features)."""
    from hwsim.energy.model import arch_features, machine_units, unit_inventory
    from models.machines import machine_for

    silicon = machine_for(arch).silicon(arch, dp)
    lights = max(1, len(scene.lights)) if scene.lit else 0
    features = arch_features(arch, scene)
    return {
        u: unit_inventory(u, dp, silicon, lights, dp.shade.method, features)
        for u in machine_units(arch)
        if u in units
    }


def _horowitz_access_pj(acc, tech: Technology, storage: Mapping[str, Any]) -> float:
    """The estimate's price of one access (:func:`hwsim.energy.model.estimate`)."""
    if acc.store != "dram":
        return tech.sram_pj(acc.word_bits, storage[acc.store].bits)
    if acc.kind == "read":
        return acc.word_bits * tech.v("energy", "dram_read_bit_pj")
    return tech.v("energy", f"dram_{acc.kind}_pj")


def _memories(arch, dp, counters, units, tech: Technology, prices: _Prices) -> dict[str, Any]:
    """Each memory's accesses priced both ways; DRAM commands the library lacks apart."""
    from models.machines import machine_for

    family = machine_for(arch)
    storage = {s.name: s for s in family.silicon(arch, dp).storage}
    out: dict[str, dict[str, Any]] = {}
    for acc in family.accesses(counters, arch, dp, units):
        row = out.setdefault(
            acc.store,
            {"actions": {}, "horowitz_joules": 0.0, "library_joules": 0.0, "not_priced": {}},
        )
        row["actions"][acc.kind] = row["actions"].get(acc.kind, 0) + acc.count
        horowitz = acc.count * _horowitz_access_pj(acc, tech, storage) * _PJ
        if acc.store == "dram" and acc.kind != "read":
            row["not_priced"][acc.kind] = row["not_priced"].get(acc.kind, 0.0) + horowitz
            continue
        if acc.store == "dram":
            library = acc.word_bits * prices.table["dram_read_bit_pj"]
        else:
            library = prices.sram_pj(acc.word_bits, storage[acc.store].bits, acc.kind)
        row["horowitz_joules"] += horowitz
        row["library_joules"] += acc.count * library * _PJ
    for row in out.values():
        row["ratio"] = _ratio(row["library_joules"], row["horowitz_joules"])
    return out


def _ratio(library: float, horowitz: float) -> float | None:
    return library / horowitz if horowitz else None


def band(
    frame, counters, units: list[str], cycles: int | None, technology: str | None = None
) -> dict[str, Any] | None:
    """The frame's dynamic energy priced by the estimate's tables and by the library, per
    unit, per memory and per frame, with ``ratio`` = library / tables (arguments as
    :func:`hwsim.energy.estimate_frame`; None where the machine declares no silicon).

    Shared: the action counts and widths.  Independent: every per-action energy (and so
    the node scaling).  Outside the band: DRAM activations and refreshes (no library
    action; ``not_priced_joules``) and leakage (``static_joules``)."""
    from hwsim.energy import arch_technology, estimate_frame

    est = estimate_frame(frame, counters, units, cycles, technology)
    if est is None:
        return None
    arch, dp = frame.arch, frame.datapath
    tech = arch_technology(arch, technology)
    prices = _Prices(tech)
    unit_rows = {}
    for u, inventory in _inventories(arch, dp, frame.scene, units).items():
        row = est["energy"]["units"][u]
        per = sum(prices.op_pj(op) for op in inventory) * _PJ
        unit_rows[u] = {
            "actions": row["actions"],
            "horowitz_joules_per_action": row["joules_per_action"],
            "library_joules_per_action": per,
            "horowitz_joules": row["joules"],
            "library_joules": per * row["actions"],
            "ratio": _ratio(per, row["joules_per_action"]),
        }
    memories = _memories(arch, dp, counters, units, tech, prices)
    rows = [*unit_rows.values(), *memories.values()]
    horowitz = sum(r["horowitz_joules"] for r in rows)
    library = sum(r["library_joules"] for r in rows)
    return {
        "technology": tech.describe(),
        "library": {"dram_type": DRAM_TYPE, **stored_prices()["library"]},
        "units": unit_rows,
        "memories": memories,
        "frame": {
            "horowitz_joules": horowitz,
            "library_joules": library,
            "ratio": _ratio(library, horowitz),
            "not_priced_joules": sum(sum(m["not_priced"].values()) for m in memories.values()),
            "static_joules": est["energy"]["static_joules"],
            "estimate_total_joules": est["energy"]["total_joules"],
        },
    }


def band_of_run(run, arch, technology: str | None = None) -> dict[str, Any]:
    """:func:`band` of a rendered frame (a :class:`hwsim.run.fidelity.RenderRun` on
    ``arch``, its :class:`~hwsim.spec.arch.ArchConfig`): only where the render priced its
    energy (the cycle and transaction rungs, one frame of the whole volume)."""
    from models.frame import frame_of

    if run.silicon is None:
        raise InputError(
            "this render counted no priced actions",
            key="--fidelity",
            allowed="cycle or transaction, on a machine with silicon, not a supervolume",
        )
    frame = frame_of(run.scene, run.volume, run.transfer, arch)
    return band(frame, run.counters, run.elaborated_units, run.cycles, technology)


def _builtin_archs() -> list:
    from hwsim.spec.arch import load_arch_file
    from models.machines import families

    files = [p for family in families() for p in family.arch_files()]
    return [load_arch_file(p) for p in sorted(files, key=lambda p: p.name)]


def _shapes() -> list[tuple[int, int]]:
    """Every ``(word_bits, array_bits)`` SRAM the built-in machines read or write: their
    tables (every feature the file declares) and buffers, at every voxel width they take."""
    from hwsim.energy.model import DATAPATH, arch_features, machine_units, unit_inventory
    from models.datapath import Datapath
    from models.machines import machine_for

    shapes = set()
    for arch in _builtin_archs():
        family = machine_for(arch)
        if family.silicon is None:
            continue  # not priced: hwsim energy refuses a machine without silicon
        for bits in arch.value_bits:
            dp = Datapath.from_arch(arch, bits)
            silicon = family.silicon(arch, dp)
            storage = {s.name: s.bits for s in silicon.storage}
            for u in machine_units(arch):
                for op in unit_inventory(u, dp, silicon, 1, dp.shade.method, arch_features(arch)):
                    if op.kind == "table":
                        shapes.add((op.a, op.a * op.b))
            for acc in family.accesses({}, arch, dp, list(DATAPATH)):
                if acc.store != "dram":
                    shapes.add((acc.word_bits, storage[acc.store]))
    return sorted(shapes)


def build_cacti() -> str:
    """Make hwcomponents-cacti's CACTI program run here: its wheel ships one built for
    glibc 2.38 (Debian 12 has 2.36) beside CACTI's source, rebuilt with ``make`` (about
    20 s, no network) when the shipped one does not start.  Returns what was done."""
    spec = importlib.util.find_spec("hwcomponents_cacti")
    if spec is None or spec.origin is None:
        raise NotAvailableError(_INSTALL)
    folder = Path(spec.origin).parent / "cacti"

    def runs() -> bool:
        probe = [str(folder / "cacti"), "-h"]
        done = subprocess.run(probe, capture_output=True, text=True, cwd=folder, check=False)
        return "how to use CACTI" in done.stdout + done.stderr

    if (folder / "cacti").is_file() and runs():
        return f"{folder / 'cacti'} runs"
    shutil.rmtree(folder / "obj_dbg", ignore_errors=True)  # objects of the wheel's build
    (folder / "cacti").unlink(missing_ok=True)
    subprocess.run(["make", "-s", "-C", str(folder)], check=True, capture_output=True)
    if not runs():
        raise NotAvailableError(f"CACTI rebuilt in {folder} does not run")
    return f"{folder / 'cacti'} rebuilt from its source"


def regenerate(path: Path) -> dict[str, Any]:
    """Price every stored entry live and write the table to ``path``."""
    shapes = _shapes()
    nodes = {}
    for name in NODES:
        node = load_technology(name).node_nm
        nodes[_node_key(node)] = {"technology": name, **live_prices(node, shapes)}
    data = {
        "schema": 1,
        "about": "hwsim/energy/accelergy.py: the library's prices (pJ) at each built-in "
        "node; regenerate with `python -m hwsim.energy.accelergy`",
        "library": library_versions(),
        "python": sys.version.split()[0],
        "nodes": nodes,
    }
    path.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    return data


def main(argv: list[str] | None = None) -> int:
    """``python -m hwsim.energy.accelergy [--out FILE] [--build-cacti]``: regenerate the
    stored prices, or only make the library's CACTI run here."""
    parser = argparse.ArgumentParser(prog="python -m hwsim.energy.accelergy")
    default = Path(str(resources.files("hwsim.energy") / "data" / _DATA))
    parser.add_argument("--out", type=Path, default=default)
    parser.add_argument(
        "--build-cacti", action="store_true", help="only make the library's CACTI run here"
    )
    args = parser.parse_args(argv)
    try:
        if args.build_cacti:
            print(build_cacti())
            return 0
        data = regenerate(args.out)
    except NotAvailableError as exc:
        print(f"hwsim: error: {exc}", file=sys.stderr)
        return 2
    shapes = len(next(iter(data["nodes"].values()))["sram"])
    print(f"{args.out}: {len(data['nodes'])} nodes, {shapes} SRAM shapes each")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
