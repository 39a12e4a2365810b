"""A silicon technology: energy per operation, area per component, gate delay, leakage.

# Ref: hwsim/energy/technologies/*.toml (every value with its source and tag, [V] [R] [I]);
#      docs/energy.md (the rules and what they leave out).

One TOML file per technology.  The base file (``cmos45``) gives its values directly; a
derived file names its ``base`` and is scaled from it by constant-field rules, then its
own tables override (external memory, leakage: they do not follow the logic rules):

* switched capacitance grows with the feature size ``L``, so dynamic energy scales by
  ``(L / L0) (V / V0)^2``;
* area by ``(L / L0)^2``; gate delay (FO4) by ``L / L0``.

Components scale with their widths by stated rules: an adder's energy and area linearly
with its width, a multiplier's with the product of its operand widths, an SRAM access
with the square root of the array's bits (Horowitz's 8 kB / 1 MB figures follow it within
15 %) and linearly with the word read, never below the word's flip-flops; storage area per
bit (SRAM cells from :data:`SRAM_MIN_BITS` bits, flip-flops below).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Literal

import msgspec
from msgspec import UNSET, UnsetType

from hwsim.core.config import read_toml
from hwsim.core.errors import InputError
from hwsim.core.models import Schema, between, validate

__all__ = [
    "FF_GATE_EQUIVALENTS",
    "SRAM_MIN_BITS",
    "Technology",
    "TechnologyFile",
    "builtin_technologies",
    "load_technology",
]

SCHEMA = 1
#: Arrays of fewer bits are built of flip-flops (a FIFO of a few entries), not SRAM.
SRAM_MIN_BITS = 4096
#: A D flip-flop in NAND2 gate equivalents (NanGate 45 nm DFF_X1 4.52 um^2 / NAND2_X1
#: 0.798 um^2 [R]).
FF_GATE_EQUIVALENTS = 5.67


# --------------------------------------------------------------------------- the file's model
# A technology file, declared once (issue 33): types, ranges, tags and the keys of each
# table are the model's; what a type cannot say (a base file's keys may be left out and
# scaled, a derived file must give its own external memory and leakage) is checked below.


class Value(Schema):
    """One value of a table, its tag ([V] verified, [R] recalled, [I] inferred) and source."""

    value: between(0.0, 1e12)
    tag: Literal["V", "R", "I"]
    source: str


class DivisorValue(Schema):
    """A value that divides somewhere (gate equivalents = area / NAND2 area, fmax =
    1 / (levels x FO4 delay)): zero is refused."""

    value: between(0.0, 1e12, open_lo=True)
    tag: Literal["V", "R", "I"]
    source: str


class EnergyTable(Schema):
    """Energy per operation in pJ (widths scale by the module docstring's rules)."""

    add_32b_pj: Value | UnsetType = UNSET
    mult_32b_pj: Value | UnsetType = UNSET
    sram_8kb_64b_pj: Value | UnsetType = UNSET
    dram_read_bit_pj: Value | UnsetType = UNSET
    dram_activate_pj: Value | UnsetType = UNSET
    dram_refresh_pj: Value | UnsetType = UNSET
    register_bit_pj: Value | UnsetType = UNSET


class AreaTable(Schema):
    """Area per component in um^2."""

    add_32b_um2: DivisorValue | UnsetType = UNSET
    mult_32b_um2: DivisorValue | UnsetType = UNSET
    sram_bit_um2: DivisorValue | UnsetType = UNSET
    nand2_um2: DivisorValue | UnsetType = UNSET


class TimingTable(Schema):
    fo4_ps: DivisorValue | UnsetType = UNSET
    gate_level_fo4: DivisorValue | UnsetType = UNSET


class LeakageTable(Schema):
    w_per_mm2: Value | UnsetType = UNSET


class TechnologyHeader(Schema):
    name: str
    node_nm: between(1.0, 10000.0)
    vdd: between(0.1, 15.0, open_lo=True)
    description: str = ""
    #: A built-in technology or a .toml file beside this one, scaled to this node.
    base: str = ""


class TechnologyFile(Schema):
    """A technology TOML file."""

    technology: TechnologyHeader
    schema: Literal[1] = SCHEMA
    energy: EnergyTable = EnergyTable()
    area: AreaTable = AreaTable()
    timing: TimingTable = TimingTable()
    leakage: LeakageTable = LeakageTable()


_TABLES = {"energy": EnergyTable, "area": AreaTable, "timing": TimingTable, "leakage": LeakageTable}
#: Keys of each table and their units, as the files name them (the model's fields).
_KEYS = {name: tuple(f.name for f in msgspec.structs.fields(t)) for name, t in _TABLES.items()}
#: How each table scales from the base node: (exponent of L / L0, exponent of V / V0).
_SCALING = {"energy": (1, 2), "area": (2, 0), "timing": (1, 0), "leakage": (0, 0)}
#: Keys that never scale by the logic rules (external memory): a derived file gives them.
_OWN = {"dram_read_bit_pj", "dram_activate_pj", "dram_refresh_pj", "w_per_mm2"}
#: A derived file's ``base`` chain: at most this many files deep.
MAX_BASE_DEPTH = 8
#: Ratios that hold at every node (a gate level in FO4): taken from the base as they are.
_RATIOS = {"gate_level_fo4"}


@dataclass(frozen=True)
class Technology:
    """One technology's values (``values[table][key]``) and where each came from."""

    name: str
    node_nm: float
    vdd: float
    description: str
    source: str
    values: dict[str, dict[str, float]]
    #: ``tags[table][key]``: (tag, source text) of every value, scaled ones included.
    tags: dict[str, dict[str, tuple[str, str]]] = field(default_factory=dict)
    base: str | None = None

    def v(self, table: str, key: str) -> float:
        return self.values[table][key]

    # ------------------------------------------------------------ energy (pJ)

    def add_pj(self, bits: int) -> float:
        """One addition (or subtraction, comparison) of ``bits``-bit operands."""
        return self.v("energy", "add_32b_pj") * bits / 32

    def mult_pj(self, a_bits: int, b_bits: int) -> float:
        """One ``a_bits`` x ``b_bits`` multiplication."""
        return self.v("energy", "mult_32b_pj") * a_bits * b_bits / 1024

    def register_pj(self, bits: int) -> float:
        """Writing ``bits`` flip-flops once (a pipeline register, a small FIFO entry)."""
        return self.v("energy", "register_bit_pj") * bits

    def sram_pj(self, word_bits: int, array_bits: int) -> float:
        """One read or write of a ``word_bits`` word of an array of ``array_bits``."""
        scaled = self.v("energy", "sram_8kb_64b_pj") * math.sqrt(array_bits / 65536)
        return max(scaled * word_bits / 64, self.register_pj(word_bits))

    # ------------------------------------------------------------ area (um^2)

    def add_um2(self, bits: int) -> float:
        return self.v("area", "add_32b_um2") * bits / 32

    def mult_um2(self, a_bits: int, b_bits: int) -> float:
        return self.v("area", "mult_32b_um2") * a_bits * b_bits / 1024

    def storage_um2(self, bits: int) -> float:
        """An array of ``bits``: SRAM cells from :data:`SRAM_MIN_BITS`, flip-flops below."""
        if bits >= SRAM_MIN_BITS:
            return self.v("area", "sram_bit_um2") * bits
        return self.gate_um2(FF_GATE_EQUIVALENTS) * bits

    def gate_um2(self, gate_equivalents: float) -> float:
        return self.v("area", "nand2_um2") * gate_equivalents

    # ------------------------------------------------------------ timing, leakage

    @property
    def gate_level_ps(self) -> float:
        """Delay of one level of generic two-input gates."""
        return self.v("timing", "fo4_ps") * self.v("timing", "gate_level_fo4")

    @property
    def leakage_w_per_mm2(self) -> float:
        return self.v("leakage", "w_per_mm2")

    def describe(self) -> dict:
        """What ``stats.json`` records of the technology."""
        return {
            "name": self.name,
            "node_nm": self.node_nm,
            "vdd": self.vdd,
            "base": self.base,
            "file": self.source,
        }


def _parse(doc: TechnologyFile, source: str, base: Technology | None) -> Technology:
    """The technology of a validated file; keys it leaves out scale from ``base``."""
    t = doc.technology
    if base is None and t.base:
        raise InputError(
            f"base technology {t.base!r} not given", source=source, key="technology.base"
        )
    values: dict[str, dict[str, float]] = {}
    tags: dict[str, dict[str, tuple[str, str]]] = {}
    for table_name, keys in _KEYS.items():
        table = getattr(doc, table_name)
        values[table_name], tags[table_name] = {}, {}
        for key in keys:
            entry = getattr(table, key)
            if entry is not UNSET:
                values[table_name][key] = entry.value
                tags[table_name][key] = (entry.tag, entry.source)
            elif base is not None and key in _RATIOS:
                values[table_name][key] = base.values[table_name][key]
                tags[table_name][key] = base.tags[table_name][key]
            elif base is not None and key not in _OWN:
                le, ve = _SCALING[table_name]
                factor = (t.node_nm / base.node_nm) ** le * (t.vdd / base.vdd) ** ve
                values[table_name][key] = base.values[table_name][key] * factor
                tag, text = base.tags[table_name][key]
                rule = f"{base.name} x {factor:.4g} (L^{le} V^{ve} scaling)"
                tags[table_name][key] = ("I" if tag != "I" else tag, f"{rule}; base: {text}")
            else:
                why = " (external memory and leakage do not scale)" if base else ""
                raise InputError("is required" + why, source=source, key=f"{table_name}.{key}")
    return Technology(
        name=t.name,
        node_nm=t.node_nm,
        vdd=t.vdd,
        description=t.description,
        source=source,
        values=values,
        tags=tags,
        base=base.name if base is not None else None,
    )


def builtin_technologies() -> dict[str, Path]:
    """The built-in technology files, by name."""
    folder = resources.files("hwsim.energy") / "technologies"
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir() if p.name.endswith(".toml")}


_CACHE: dict[str, Technology] = {}


def load_technology(name_or_path: str) -> Technology:
    """A technology by built-in name (``cmos45``, ``cmos250``, ``cmos350``) or from a
    TOML file; a derived file's ``base`` is looked up the same way (relative paths from the
    file's folder).  A ``base`` chain that comes back to a file it passed, or is deeper than
    :data:`MAX_BASE_DEPTH`, is refused naming the chain."""
    return _load(name_or_path, ())


def _locate(name_or_path: str, chain: tuple[tuple[str, str], ...]) -> tuple[Path, str]:
    """The file of ``name_or_path`` and its name in messages; ``chain`` is the
    (resolved path, source) of each file whose ``base`` led here."""
    builtins = builtin_technologies()
    if name_or_path in builtins:
        path = builtins[name_or_path]
        return path, f"hwsim/energy/technologies/{path.name}"
    if name_or_path.endswith(".toml") or "/" in name_or_path:
        return Path(name_or_path), name_or_path
    allowed = ", ".join(sorted(builtins)) + ", or a .toml file"
    message = f"unknown technology {name_or_path!r}"
    if chain:
        raise InputError(message, source=chain[-1][1], key="technology.base", allowed=allowed)
    raise InputError(message, key="--technology", allowed=allowed)


def _load(name_or_path: str, chain: tuple[tuple[str, str], ...]) -> Technology:
    if name_or_path in _CACHE:
        return _CACHE[name_or_path]
    path, source = _locate(name_or_path, chain)
    resolved = str(path.resolve())
    names = " -> ".join([*(s for _, s in chain), source])
    if resolved in (r for r, _ in chain):
        raise InputError(
            f"base chain comes back to a file it passed: {names}",
            source=chain[-1][1],
            key="technology.base",
            allowed="a chain of other files",
        )
    if len(chain) >= MAX_BASE_DEPTH:
        raise InputError(
            f"base chain deeper than {MAX_BASE_DEPTH} files: {names}",
            source=chain[-1][1],
            key="technology.base",
            allowed=f"at most {MAX_BASE_DEPTH} files",
        )
    try:
        data = read_toml(path)
    except InputError as exc:
        if not chain:
            raise
        raise InputError(  # named by the file whose base it is
            f"base {str(path)!r}: {exc.message}",
            source=chain[-1][1],
            key="technology.base",
            allowed=exc.allowed or "a built-in technology or a .toml file beside this one",
        ) from None
    doc = validate(data, TechnologyFile, source)
    base_name, base = doc.technology.base, None
    if base_name:
        found = base_name if base_name in builtin_technologies() else str(path.parent / base_name)
        base = _load(found, (*chain, (resolved, source)))
    tech = _parse(doc, source, base)
    _CACHE[name_or_path] = tech
    return tech
