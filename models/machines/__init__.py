"""The machines: one package per family behind one :class:`Machine` interface.

# Ref: docs/architectures.md ("The machine packages": the map and how to add a machine).

``models/machines/<family>/`` holds everything one family is: its architecture files
(``*.toml``), memory layout, cycle model, transaction model, faults type and the units
only it has; ``machine.py`` in the package declares its :class:`Machine`.  Shared by
every family, and importable by ``rtl/``: :mod:`models.machines.common`.

The registry holds the families by name; an architecture file names its family
(``[pipeline] family``), or else gets the first family registered for its processing
order.  The rungs, ``hwsim archs``, the ladder, trade, figures and sweeps ask it; no
module outside a family's package names the family's classes.  Adding a machine is its
package plus one line of :data:`FAMILIES` (or :func:`register` at run time, as the test
suite does with a toy machine).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from hwsim.core.errors import NotAvailableError
from hwsim.core.models import Schema, validate
from hwsim.spec.arch import ArchConfig

__all__ = [
    "FAMILIES",
    "Machine",
    "check_tables",
    "families",
    "machine_for",
    "orders",
    "register",
    "single_frames",
    "unregister",
]

#: The built-in families, by module that declares each one's :class:`Machine`.
FAMILIES = (
    "models.machines.cube4.machine",
    "models.machines.volumepro.machine",
    "models.machines.vizard2.machine",
    "models.machines.cube1.machine",
    "models.machines.vogue.machine",
    "models.machines.cube3.machine",
    "models.machines.texslicer.machine",
    "models.machines.virim.machine",
)


def single_frames(machine_class: type) -> Callable[..., Any]:
    """The :attr:`Machine.cycle` of a cycle-model class that times single frames only:
    ``machine_class(backend, faults=, trace=).run(progress)``."""

    def cycle(backend, *, faults, trace, progress, steady_state=False):
        return machine_class(backend, faults=faults, trace=trace).run(progress)

    cycle.__doc__ = f"One frame on {machine_class.__name__} (single frames only)."
    return cycle


@dataclass(frozen=True)
class Machine:
    """One machine family as the rungs see it.

    Attributes
    ----------
    name : str
        The family (``cube4``); its package is ``models.machines.<name>``.
    orders : tuple of str
        The processing orders it models.
    cycle : callable or None
        ``cycle(backend, *, faults, trace, progress, steady_state)`` runs the back end's
        frame on the cycle model (every unit elaborated when ``backend.exercise_unused``)
        and returns a :class:`~models.machines.common.results.CycleResult`; ``None``: no
        cycle model.
    transaction : callable or None
        ``transaction(frame, **options)`` builds the frame's event model (its ``run()``
        gives the timing); ``None``: no transaction model.
    faults_type : type or None
        The structures the cycle model can break (fault-injection tests).
    steady_state : bool
        Whether the cycle and transaction models time back-to-back frames.
    check_frame : callable or None
        ``check_frame(frame)`` refuses (:class:`~hwsim.core.errors.InputError`, key named)
        what the family's models cannot render; asked before every machine rung
        (functional, transaction, cycle, rtl), so they refuse alike.
    rtl_top : str or None
        The module of the family's RTL top, where one exists.
    rtl_archs : callable or None
        ``rtl_archs(arch)``: whether the RTL top renders ``arch`` (a top built for some
        of the family's machines, e.g. the VolumePro 500's and not the VolumePro
        1000's); ``None``: every architecture of the family.
    silicon : callable or None
        ``silicon(arch, datapath)``: the machine's buffers and interpolator, a
        :class:`~models.machines.common.silicon.Silicon` (the energy and area model).
    accesses : callable or None
        ``accesses(counters, arch, datapath, units)``: a frame's memory actions
        (:class:`~models.machines.common.silicon.Access`) from its counters.
    package : str
        The package holding the family's architecture files.
    split : type or None
        ``split(frame, faults)``: the family's frame split by rays across workers (its
        ``bands(n)``, ``task`` and ``combine(results)``; e.g.
        :class:`models.machines.cube4.bands.BandSplit`); None: frames run in one process.
    buffers : type or None
        The model of the family's ``[buffers]`` table (a :class:`hwsim.core.models.Schema`:
        its keys, types and ranges); None: the family has no buffers to size.
    check_arch : callable or None
        ``check_arch(arch)``: the family's rules across an architecture file's tables
        (e.g. VIZARD II's one memory channel), raising :class:`InputError` naming the key.
    independence : dict or None
        What the family's transaction rung shares with its cycle rung on frame cycles
        (``verdict``: shared, partly shared or independent; ``shared``: dotted names;
        ``txn`` and ``cycle``: what each side computes on its own), for a family outside
        :data:`hwsim.studies.trade.independence.TRANSACTION_VS_CYCLE`.
    skew_memory : bool
        The family's cycle rung reads voxels through the skewed-memory address unit
        (:mod:`models.units.skew`, its ``LATENCY`` in the timing rules), so ``hwsim
        archs`` checks that unit's clock beside the datapath's.

    :func:`check_tables` asks ``buffers`` and ``check_arch`` when a file is loaded.
    """

    name: str
    orders: tuple[str, ...]
    cycle: Callable[..., Any] | None
    transaction: Callable[..., Any] | None
    faults_type: type | None = None
    steady_state: bool = False
    check_frame: Callable[..., None] | None = None
    rtl_top: str | None = None
    rtl_archs: Callable[[ArchConfig], bool] | None = None
    package: str = field(default="")
    silicon: Callable[..., Any] | None = None
    accesses: Callable[..., Any] | None = None
    split: type | None = None
    buffers: type | None = None
    check_arch: Callable[..., None] | None = None
    independence: dict[str, Any] | None = None
    skew_memory: bool = False

    def arch_files(self) -> list[Path]:
        """The family's built-in architecture files."""
        if not self.package:
            return []
        folder = resources.files(self.package)
        return [Path(str(p)) for p in folder.iterdir() if p.name.endswith(".toml")]


_registry: dict[str, Machine] = {}  # by family name, in registration order
_loaded = False


def _load() -> dict[str, Machine]:
    """The registry, with the built-in families loaded first on first use."""
    global _loaded
    if not _loaded:
        _loaded = True
        added = dict(_registry)
        _registry.clear()
        for module in FAMILIES:
            register(importlib.import_module(module).MACHINE)
        _registry.update(added)
    return _registry


def register(machine: Machine) -> None:
    """Add ``machine`` under its name (replacing a family of that name)."""
    _registry[machine.name] = machine


def unregister(machine: Machine) -> None:
    """Remove ``machine`` (a family added at run time, e.g. by a test)."""
    if _registry.get(machine.name) is machine:
        del _registry[machine.name]


class _NoBuffers(Schema):
    """``[buffers]`` of a machine no family models, or of a family with no buffers."""


def check_tables(arch: ArchConfig) -> ArchConfig:
    """Validate the tables of ``arch`` whose meaning the models own, before any work:
    ``[formats]`` (:data:`models.datapath.FormatsTable`), ``[buffers]`` (the family's
    :attr:`Machine.buffers` model) and the family's rules across tables
    (:attr:`Machine.check_arch`).  Called by every path that loads an architecture file
    (:func:`hwsim.run.fidelity.resolve_arch`, :func:`~hwsim.run.fidelity.builtin_archs`).
    A file whose family is unknown is refused later, by the rung that needs the family
    (:func:`machine_for`); its ``[buffers]`` must then be empty.

    Raises
    ------
    InputError
        One line naming the file, the key path and what is allowed.
    """
    from models.datapath import Datapath

    Datapath.from_arch(arch, 0)
    try:
        family: Machine | None = machine_for(arch)
    except NotAvailableError:
        family = None
    model = family.buffers if family is not None and family.buffers is not None else _NoBuffers
    validate(arch.buffers, model, arch.source, prefix="buffers")
    if family is not None and family.check_arch is not None:
        family.check_arch(arch)
    return arch


def families() -> list[Machine]:
    """Every registered family, in registration order."""
    return list(_load().values())


def orders() -> tuple[str, ...]:
    """Every processing order some family models."""
    return tuple(dict.fromkeys(o for m in families() for o in m.orders))


def machine_for(arch: ArchConfig, rung: str | None = None) -> Machine:
    """The family modelling ``arch``: its ``family`` key, else the first family registered
    for its processing order.  With ``rung`` (``"cycle"`` or ``"transaction"``), a
    :class:`~hwsim.core.errors.NotAvailableError` naming what is modelled when the family has
    no model at that rung."""
    registry = _load()
    if arch.family:
        machine = registry.get(arch.family)
        if machine is None:
            raise NotAvailableError(
                f"{arch.name}: no machine family {arch.family!r}",
                source=arch.source,
                key="pipeline.family",
                allowed=", ".join(registry),
            )
        if arch.order not in machine.orders:
            raise NotAvailableError(
                f"{arch.name}: family {arch.family} does not model the {arch.order} order",
                source=arch.source,
                key="pipeline.order",
                allowed=", ".join(machine.orders),
            )
    else:
        machine = next((m for m in registry.values() if arch.order in m.orders), None)
        if machine is None:
            raise NotAvailableError(
                f"{arch.name} ({arch.order} order) has no machine model",
                key="--arch",
                allowed=f"a machine of order {', '.join(orders())}",
            )
    if rung is not None and getattr(machine, rung) is None:
        modelled = [m.name for m in registry.values() if getattr(m, rung) is not None]
        raise NotAvailableError(
            f"{arch.name} ({machine.name} family) is not modelled at {rung} fidelity",
            key="--arch",
            allowed=f"a machine of family {', '.join(modelled)}",
        )
    return machine
