"""Which (scene, machine, rung) cells a trade measures, and why the others are not run.

# Ref: docs/sweeps.md ("The fidelity-ladder trade"); hwsim/spec/machine_features.py (the
#      machines' declared features, the one check every rung asks).

The default product is what each machine had, as published: the rungs that model it
(:func:`hwsim.run.fidelity.machine_rungs`) times the scenes inside its declared features
and limits (:func:`hwsim.run.fidelity.check_scene_fits`, ``[limits]``).  A scene asking a
feature the machine never had is a *what-if*, measured only with ``extend`` (its rows have
status ``what-if``); one no rung can model there (perspective on a parallel-only order,
say) is never measured.  A cell left out is listed once in :class:`NotRun` with its
reason, not as a row, unless the user named both its machine and its rung: then it is a
row whose status and ``note`` say why (``unsupported``, ``not available``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hwsim.core.errors import InputError
from hwsim.spec.arch import ArchConfig

__all__ = [
    "NOT_AVAILABLE",
    "UNSUPPORTED",
    "WHAT_IF",
    "NotRun",
    "TradeRows",
    "Verdict",
    "cell_verdict",
    "scene_verdict",
]

#: Row statuses beside ``ok``: measured outside the machine's features; refused by the
#: machine (as the hardware did) or by a rung's own limits; a rung that does not model it.
WHAT_IF, UNSUPPORTED, NOT_AVAILABLE = "what-if", "unsupported", "not available"


@dataclass(frozen=True)
class Verdict:
    """Whether a cell is measured (``ok``, ``what-if``) or why not: ``reason``, the
    machine's one-line refusal, and ``short``, the same without the machine's name and
    sources where it can be said so (cells of several machines then share one note)."""

    status: str
    reason: str = ""
    short: str = ""

    @property
    def runs(self) -> bool:
        """Whether the cell is rendered."""
        return self.status in ("ok", WHAT_IF)


def scene_verdict(scene: Any, volume: Any, machine: ArchConfig, *, extend: bool) -> Verdict:
    """Whether ``machine`` renders ``scene`` on ``volume`` by its declared features and
    limits: ``ok``; ``what-if`` (outside them, ``extend`` given); else ``unsupported``
    with the machine's refusal (the message ``hwsim render`` prints)."""
    from hwsim.run.fidelity import check_scene_fits, check_volume_fits, value_path_volume
    from hwsim.run.supervolume import oversize

    try:
        value_path_volume(scene, volume, machine)  # voxel bits: never a what-if
        check_scene_fits(scene, machine, extend=True)  # no rung models these there
    except InputError as always:
        return Verdict(UNSUPPORTED, always.message, always.message)
    try:
        check_scene_fits(scene, machine, extend=False)
        if oversize(volume, machine) and not machine.supervolumes:
            check_volume_fits(volume, machine)  # refuses, naming limits.max_volume
    except InputError as strict:
        if extend:
            return Verdict(WHAT_IF, strict.message)
        short = _outside(scene, machine) or strict.message
        return Verdict(UNSUPPORTED, strict.message, f"{short}; --extend measures it as a what-if")
    return Verdict("ok")


def _outside(scene: Any, machine: ArchConfig) -> str:
    """The first feature ``scene`` asks outside ``machine``, without the machine's name:
    ``no xray (render.mode)``; empty when none (the volume is over its limits)."""
    from hwsim.run.fidelity import algorithms
    from hwsim.spec.machine_features import scene_extensions

    extensions = scene_extensions(scene, machine, algorithms(machine))
    return f"no {extensions[0].asked} ({extensions[0].key})" if extensions else ""


def cell_verdict(machine: ArchConfig, rung: str, scene: Verdict) -> Verdict:
    """The verdict of ``rung`` on ``machine`` for a scene whose verdict is ``scene``: the
    rung's absence first (it holds for every scene), then the scene's."""
    from hwsim.run.fidelity import machine_rungs

    rungs = machine_rungs(machine)
    if rung not in rungs:
        reason = f"no {rung} model of {machine.name} (its rungs: {', '.join(rungs)})"
        return Verdict(NOT_AVAILABLE, reason, f"no {rung} model of the machine")
    return scene


class NotRun:
    """The cells left out of a trade, each reason once: the machines, scenes and rungs a
    reason covers (all the combinations of them), ``every scene`` / ``every rung`` when
    all of the trade's."""

    def __init__(self, scenes: list[str], rungs: list[str]) -> None:
        self.scenes, self.rungs = scenes, rungs
        self._cells: dict[tuple[str, str, str], dict[str, Any]] = {}

    def add(self, scene: str, arch: str, rung: str, verdict: Verdict) -> None:
        """Leave out ``(scene, arch, rung)`` for ``verdict``'s reason."""
        short = verdict.short or verdict.reason
        key = (arch, verdict.status, verdict.reason)
        new = {"status": verdict.status, "reason": short, "detail": verdict.reason}
        entry = self._cells.setdefault(key, {**new, "scenes": [], "rungs": []})
        for field, value in (("scenes", scene), ("rungs", rung)):
            if value not in entry[field]:
                entry[field].append(value)

    def entries(self) -> list[dict[str, Any]]:
        """The left-out cells as plain data (``trade.json``'s ``not_run``): ``archs``,
        ``scenes``, ``rungs``, ``status``, the ``reason`` they share, each machine's own
        message in ``details``, and the one-line ``text`` the tables print."""
        merged: dict[tuple, dict[str, Any]] = {}
        for (arch, _, _), e in self._cells.items():
            key = (e["status"], e["reason"], tuple(e["scenes"]), tuple(e["rungs"]))
            group = merged.setdefault(key, {"archs": [], **e, "details": {}})
            group["archs"].append(arch)
            group["details"][arch] = e["detail"]
        out = []
        for e in merged.values():
            del e["detail"]
            where = "every scene" if e["scenes"] == self.scenes else ", ".join(e["scenes"])
            when = "every rung" if e["rungs"] == self.rungs else ", ".join(e["rungs"])
            text = f"{where} at {when} on {', '.join(e['archs'])}: {e['reason']}"
            out.append({**e, "text": text})
        return out


class TradeRows(list):
    """The rows of a trade (one dict per measured cell, or per empty cell the user named)
    and ``not_run``: the cells left out of the product, each reason once."""

    def __init__(self, rows: list[dict[str, Any]], not_run: list[dict[str, Any]]) -> None:
        super().__init__(rows)
        self.not_run = not_run
