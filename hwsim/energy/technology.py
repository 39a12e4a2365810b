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

from hwsim.core.config import Table, read_toml
from hwsim.core.errors import InputError

__all__ = [
    "FF_GATE_EQUIVALENTS",
    "SRAM_MIN_BITS",
    "Technology",
    "builtin_technologies",
    "load_technology",
]

SCHEMA = 1
#: Arrays of fewer bits are built of flip-flops (a FIFO of a few entries), not SRAM.
SRAM_MIN_BITS = 4096
#: A D flip-flop in NAND2 gate equivalents (NanGate 45 nm DFF_X1 4.52 um^2 / NAND2_X1
#: 0.798 um^2 [R]).
FF_GATE_EQUIVALENTS = 5.67

#: Keys of each table and their units, as the files name them.
_KEYS = {
    "energy": (
        "add_32b_pj",
        "mult_32b_pj",
        "sram_8kb_64b_pj",
        "dram_read_bit_pj",
        "dram_activate_pj",
        "dram_refresh_pj",
        "register_bit_pj",
    ),
    "area": ("add_32b_um2", "mult_32b_um2", "sram_bit_um2", "nand2_um2"),
    "timing": ("fo4_ps", "gate_level_fo4"),
    "leakage": ("w_per_mm2",),
}
#: How each table scales from the base node: (exponent of L / L0, exponent of V / V0).
_SCALING = {"energy": (1, 2), "area": (2, 0), "timing": (1, 0), "leakage": (0, 0)}
#: Keys that never scale by the logic rules (external memory): a derived file gives them.
_OWN = {"dram_read_bit_pj", "dram_activate_pj", "dram_refresh_pj", "w_per_mm2"}
#: Tables whose values are divisors somewhere (gate equivalents = area / NAND2 area,
#: fmax = 1 / (levels x FO4 delay)): zero is refused at load.
_POSITIVE = {"area", "timing"}
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


def _parse(data: dict, source: str, base: Technology | None) -> Technology:
    top = Table(data, source)
    top.schema(SCHEMA)
    t = top.table("technology", required=True)
    name = t.string("name")
    node = t.number("node_nm", lo=1.0, hi=10000.0)
    vdd = t.number("vdd", lo=0.1, hi=15.0, lo_open=True)
    description = t.string("description", "")
    base_name = t.string("base", "")
    t.finish()
    if base is None and base_name:
        raise t.error("base", f"base technology {base_name!r} not given")
    values: dict[str, dict[str, float]] = {}
    tags: dict[str, dict[str, tuple[str, str]]] = {}
    for table_name, keys in _KEYS.items():
        table = top.table(table_name)
        values[table_name], tags[table_name] = {}, {}
        for key in keys:
            if table.has(key):
                entry = table.table(key)
                # Areas and delays divide (gate equivalents, fmax): strictly positive.
                positive = table_name in _POSITIVE
                values[table_name][key] = entry.number("value", lo=0.0, hi=1e12, lo_open=positive)
                tag = entry.choice("tag", ("V", "R", "I"))
                tags[table_name][key] = (tag, entry.string("source"))
                entry.finish()
            elif base is not None and key in _RATIOS:
                values[table_name][key] = base.values[table_name][key]
                tags[table_name][key] = base.tags[table_name][key]
            elif base is not None and key not in _OWN:
                le, ve = _SCALING[table_name]
                factor = (node / base.node_nm) ** le * (vdd / base.vdd) ** ve
                values[table_name][key] = base.values[table_name][key] * factor
                tag, text = base.tags[table_name][key]
                rule = f"{base.name} x {factor:.4g} (L^{le} V^{ve} scaling)"
                tags[table_name][key] = ("I" if tag != "I" else tag, f"{rule}; base: {text}")
            else:
                why = " (external memory and leakage do not scale)" if base else ""
                raise table.error(key, "is required" + why)
        table.finish()
    top.finish()
    return Technology(
        name=name,
        node_nm=node,
        vdd=vdd,
        description=description,
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
    base_name = Table(data, source).table("technology", required=True).string("base", "")
    base = None
    if base_name:
        found = base_name if base_name in builtin_technologies() else str(path.parent / base_name)
        base = _load(found, (*chain, (resolved, source)))
    tech = _parse(data, source, base)
    _CACHE[name_or_path] = tech
    return tech
