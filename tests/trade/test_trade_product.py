"""Issue 32: the default trade is what each machine has, as published (no ``unsupported``
row, each left-out cell said once); what-ifs only with ``--extend``, marked in every
output; an empty cell the user named shows its reason in the table itself.

The expected sets come from the machines' declared features and registered rungs, so a
new machine is covered without editing these tests."""

from __future__ import annotations

import csv
import json

import pytest

import hwsim.run.fidelity as fidelity
from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.spec.machine_features import require_machine
from hwsim.studies.trade import ladder_cases

pytestmark = pytest.mark.model

#: The trade at tiny size, as tests/system/test_readme.py shrinks the README's command.
SHRINK = ["--image", "16", "--size", "16"]


def inside(scene, machine) -> bool:
    """Whether ``scene`` asks nothing outside ``machine``'s declared features."""
    try:
        require_machine(scene, machine, fidelity.algorithms(machine), extend=False)
    except InputError:
        return False
    return True


def family_refuses(case, machine) -> bool:
    """Whether the machine's family refuses the case's frame whatever its features (e.g.
    Cube-1: any view but the six axis views): never a what-if."""
    from hwsim.spec.transfer import resolve_transfer
    from models.frame import frame_of

    transfer = resolve_transfer(case.scene.transfer, case.volume)
    try:
        fidelity.check_family(frame_of(case.scene, case.volume, transfer, machine))
    except InputError:
        return True
    return False


def cells(rungs: list[str], archs: list[str] | None = None) -> tuple[set, set]:
    """Every (scene, machine, rung) of the tiny trade, and those the machine has: a rung
    that models it and a scene inside its features that its family does not refuse."""
    machines = fidelity.builtin_archs()
    names = archs or list(machines)
    every, have = set(), set()
    for case in ladder_cases((), 16, 16):
        for name in names:
            machine = machines[name]
            fenced = family_refuses(case, machine)
            for rung in rungs:
                every.add((case.label, name, rung))
                if rung in fidelity.machine_rungs(machine) and inside(case.scene, machine):
                    if not fenced:
                        have.add((case.label, name, rung))
    return every, have


def fenced_cells(rungs: list[str]) -> set:
    """The cells whose machine's family refuses the scene (left out even with --extend)."""
    machines = fidelity.builtin_archs()
    return {
        (case.label, name, rung)
        for case in ladder_cases((), 16, 16)
        for name, machine in machines.items()
        if family_refuses(case, machine)
        for rung in rungs
        if rung in fidelity.machine_rungs(machine)
    }


def trade(tmp_path, capsys, *argv: str) -> tuple[dict, str, str, list[dict]]:
    """Run ``hwsim trade`` at tiny size: its JSON, printed table, trade.md and CSV rows."""
    out = tmp_path / "trade"
    assert main(["trade", *SHRINK, *argv, "--out", str(out)]) == 0
    with open(out / "trade.csv") as fh:
        table = list(csv.DictReader(fh))
    assert (out / "trade.png").read_bytes()[:4] == b"\x89PNG"
    data = json.loads((out / "trade.json").read_text())
    return data, capsys.readouterr().out, (out / "trade.md").read_text(), table


def table_line(lines: list[str], row: dict) -> str:
    """The printed table's line of ``row``."""
    (line,) = [
        x
        for x in lines
        if x.startswith(f"{row['scene']} ") and f" {row['arch']} " in x and f" {row['rung']} " in x
    ]
    return line


def left_out(data: dict) -> list[tuple[str, str, str]]:
    """The cells the ``not_run`` entries cover (all combinations of each entry's lists)."""
    return [
        (scene, arch, rung)
        for e in data["not_run"]
        for arch in e["archs"]
        for scene in e["scenes"]
        for rung in e["rungs"]
    ]


@pytest.mark.parametrize("rungs", ["golden,functional", "golden,functional,transaction,cycle"])
def test_the_default_set_is_what_each_machine_has(tmp_path, capsys, rungs):
    data, printed, md, table = trade(tmp_path, capsys, "--rungs", rungs)
    every, have = cells(rungs.split(","))
    measured = {(r["scene"], r["arch"], r["rung"]) for r in data["rows"] if r["arch"] != "ideal"}
    assert measured == have
    assert {r["status"] for r in data["rows"]} == {"ok"} == {r["status"] for r in table}
    # none left empty but Cube-1, which projects from the six axis views only: the
    # trade's scenes are oblique (its family refuses them, never a what-if)
    assert {arch for _, arch, _ in have} == set(fidelity.builtin_archs()) - {"cube1"}
    assert sorted(left_out(data)) == sorted(every - have)  # each left-out cell once
    assert data["not_run"] and "unsupported" not in printed and "what-if [" not in printed
    fenced = fenced_cells(rungs.split(","))
    for entry in data["not_run"]:
        assert entry["status"] == "unsupported"
        covered = {
            (s, a, r) for a in entry["archs"] for s in entry["scenes"] for r in entry["rungs"]
        }
        assert "--extend measures it" in entry["reason"] or covered <= fenced
        assert f"  {entry['text']}" in printed.splitlines() and f"- {entry['text']}" in md


def test_what_ifs_come_only_with_extend_and_are_marked_in_every_output(tmp_path, capsys):
    data, printed, md, table = trade(tmp_path, capsys, "--rungs", "golden,functional", "--extend")
    every, have = cells(["golden", "functional"])
    rows = [r for r in data["rows"] if r["arch"] != "ideal"]
    fenced = fenced_cells(["golden", "functional"])
    assert {(r["scene"], r["arch"], r["rung"]) for r in rows} == every - fenced
    assert set(left_out(data)) == fenced  # a family's refusal is never a what-if
    lines = printed.splitlines()
    for row, csv_row in zip(data["rows"], table, strict=True):
        cell = (row["scene"], row["arch"], row["rung"])
        assert csv_row["status"] == row["status"]
        if row["arch"] == "ideal" or cell in have:
            assert row["status"] == "ok" and row["extensions"] == []
            continue
        assert row["status"] == "what-if" and row["extensions"] and row["note"]
        mark = table_line(lines, row).rsplit(" ", 1)[1]
        assert f"{mark} {row['note']}" in lines
        assert f"what-if {mark} |" in md and f"{mark} {row['note']}" in md


def test_a_named_combination_outside_the_machine_is_a_row_with_its_reason(tmp_path, capsys):
    """Naming both the machine and the rungs asks for every combination: the empty ones
    are rows, their status marked [n] in the table and the reason listed under it."""
    argv = ["--arch", "volumepro500", "--rungs", "golden,functional,rtl"]
    data, printed, md, _ = trade(tmp_path, capsys, *argv)
    every, have = cells(["golden", "functional", "rtl"], ["volumepro500"])
    rows = {(r["scene"], r["arch"], r["rung"]): r for r in data["rows"] if r["arch"] != "ideal"}
    assert set(rows) == every and not data["not_run"]
    machine = fidelity.resolve_arch("volumepro500")
    empty = [r for cell, r in rows.items() if cell not in have]
    assert empty and all(r["wall_seconds"] is None for r in empty)
    lines = printed.splitlines()
    for row in empty:
        modelled = row["rung"] in fidelity.machine_rungs(machine)
        expected = "unsupported" if modelled else "not available"
        assert row["status"] == expected and row["note"]
        line = table_line(lines, row)
        mark = line.rsplit(" ", 1)[1]
        assert line.endswith(f"  {expected} {mark}") and f"{mark} {row['note']}" in lines
        assert f"{expected} {mark} |" in md and f"{mark} {row['note']}" in md
    assert any("has no iso" in r["note"] for r in empty)  # the machine's own refusal


def test_the_api_returns_the_rows_and_what_was_left_out(tmp_path):
    import hwsim

    rows = hwsim.trade(image=16, size=16, rungs="golden", out=tmp_path / "t")
    every, have = cells(["golden"])
    assert {(r["scene"], r["arch"], r["rung"]) for r in rows if r["arch"] != "ideal"} == have
    assert {r["status"] for r in rows} == {"ok"}
    assert sorted(left_out({"not_run": rows.not_run})) == sorted(every - have)
    saved = json.loads((tmp_path / "t" / "trade.json").read_text())
    assert saved["not_run"] == rows.not_run
