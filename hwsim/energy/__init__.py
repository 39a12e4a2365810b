"""Energy per frame and silicon area: action counts times per-action energies (issue 19).

# Ref: docs/energy.md.
"""

from __future__ import annotations

from typing import Any

from hwsim.core.errors import InputError
from hwsim.energy.model import estimate
from hwsim.energy.technology import Technology, builtin_technologies, load_technology

__all__ = [
    "Technology",
    "arch_technology",
    "builtin_technologies",
    "estimate",
    "estimate_frame",
    "load_technology",
    "units_below_clock",
]


def arch_technology(arch, technology: str | None = None) -> Technology:
    """The technology a frame on ``arch`` is estimated in: ``technology`` (``--technology``)
    when given, else the machine's ``[silicon] technology``, an unknown one refused naming
    the architecture file and that key (never a flag the user did not give).  The render
    calls this before the frame, so a bad node costs no simulation."""
    if technology is not None or arch is None:
        return load_technology(technology)
    try:
        return load_technology(arch.technology)
    except InputError as exc:
        if exc.key != "--technology":  # a fault inside the technology file: its own name
            raise
        raise InputError(
            exc.message, source=arch.source, key="silicon.technology", allowed=exc.allowed
        ) from None


def units_below_clock(arch, technology: str | None = None) -> list[tuple[str, float]]:
    """``(unit, fmax_hz)`` of each datapath unit of ``arch`` whose synthesised RTL cannot
    run at the machine's clock in ``technology`` (default: the machine's own node); only
    units the machine has, of the RTL's kind (:func:`~hwsim.energy.model.rtl_kind_differs`),
    and the skewed memory's address unit where the family has one (``skew_memory``); none
    for a family without a silicon model (its units are not this project's RTL)."""
    from hwsim.energy.model import machine_units, rtl_kind_differs
    from hwsim.energy.synth import unit_silicon
    from models.datapath import Datapath
    from models.machines import machine_for

    family = machine_for(arch)
    if family.silicon is None:
        return []  # no silicon model: the project's RTL units are not this machine's
    tech = arch_technology(arch, technology)
    dp = Datapath.from_arch(arch, max(arch.value_bits))
    units = [u for u in machine_units(arch) if not rtl_kind_differs(u, dp)]
    if family.skew_memory:
        units.append("skew")
    out = []
    for unit in units:
        syn = unit_silicon(unit, tech, arch.clock_hz)
        if syn is not None and syn["meets_clock"] is False:
            out.append((unit, syn["fmax_hz"]))
    return out


def estimate_frame(
    frame, counters, units: list[str], cycles: int | None, technology: str | None = None
) -> dict[str, Any] | None:
    """:func:`estimate` of a rendered ``frame`` (a :class:`models.frame.Frame`) in
    ``technology`` (default: its machine's ``[silicon] technology``); None when the
    machine's family declares no silicon."""
    from models.machines import machine_for

    arch = frame.arch
    if machine_for(arch).silicon is None:
        return None
    tech = arch_technology(arch, technology)
    return estimate(
        arch=arch,
        dp=frame.datapath,
        scene=frame.scene,
        counters=counters,
        units=units,
        cycles=cycles,
        tech=tech,
    )
