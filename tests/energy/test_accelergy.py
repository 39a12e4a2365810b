"""Energy cross-checked by Accelergy's component library (hwsim/energy/accelergy.py).

What the two prices share and what they do not: both price the same action counts at the
same widths (a frame's counters doubled double both sides); the per-action energies are
independent (a technology file's price moved moves only the tables' side, the library's
stored price moved moves only its side).  The stored library prices are re-derived live
where the library is installed (the ``energy`` extra); without it the library is one
line naming the extra, exit status 2.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import pytest

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.energy import accelergy, load_technology
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.frame import frame_of

pytestmark = pytest.mark.model

MACHINES = {"volumepro500": "cycle", "cube4": "cycle", "vizard2": "transaction"}


def _library_installed() -> bool:
    try:
        accelergy._library()
    except NotAvailableError:
        return False
    return True


needs_library = pytest.mark.skipif(
    not _library_installed(), reason="Accelergy's library not installed (the energy extra)"
)


@pytest.fixture(scope="module")
def frames():
    """Each machine's real render of a 24^3 head: (frame, counters, units, cycles)."""
    volume = make_phantom("head", size=24)
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=30, elevation=15, width=24, height=24),
    )
    out = {}
    for name, rung in MACHINES.items():
        arch = resolve_arch(name)
        done = render(scene, fidelity=rung, arch=arch, volume=volume)
        frame = frame_of(scene, volume, resolve_transfer(scene.transfer, volume), arch)
        out[name] = (frame, done.counters, done.elaborated_units, done.cycles, done.silicon)
    return out


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("technology", [None, "cmos45"])
def test_band_of_a_real_render(frames, name, technology):
    frame, counters, units, cycles, silicon = frames[name]
    band = accelergy.band(frame, counters, units, cycles, technology)
    est = silicon if technology is None else None
    assert set(band["units"]) == {u for u in units if u in band["units"]} and band["units"]
    for unit, row in band["units"].items():
        assert row["actions"] > 0, unit
        for key in ("horowitz_joules_per_action", "library_joules_per_action", "ratio"):
            assert math.isfinite(row[key]) and row[key] > 0, (unit, key)
    for store, row in band["memories"].items():
        assert row["library_joules"] > 0 and math.isfinite(row["ratio"]), store
    f = band["frame"]
    assert math.isfinite(f["ratio"]) and f["ratio"] > 0
    # The tables' side is the estimate's own dynamic energy: nothing repriced.
    parts = f["horowitz_joules"] + f["not_priced_joules"] + f["static_joules"]
    assert parts == pytest.approx(f["estimate_total_joules"], rel=1e-12)
    if est is not None:
        assert f["estimate_total_joules"] == est["energy"]["total_joules"]
        for unit, row in band["units"].items():
            assert row["actions"] == est["energy"]["units"][unit]["actions"]


def test_era_nodes_price_far_below_the_tables_and_45nm_above(frames):
    """The library takes no supply voltage and grows with sqrt(L) above 130 nm: at
    0.35 um 3.3 V it prices every unit below the tables' constant-field figure; at 45 nm,
    its own range, every unit above Horowitz's (Aladdin's operators cost more)."""
    frame, counters, units, cycles, _ = frames["volumepro500"]
    era = accelergy.band(frame, counters, units, cycles)
    modern = accelergy.band(frame, counters, units, cycles, "cmos45")
    assert all(r["ratio"] < 0.5 for r in era["units"].values())
    assert all(1.5 < r["ratio"] < 6 for r in modern["units"].values())


def test_both_sides_price_the_same_action_counts(frames):
    frame, counters, units, cycles, _ = frames["volumepro500"]
    one = accelergy.band(frame, counters, units, cycles)
    two = accelergy.band(frame, {k: 2 * v for k, v in counters.items()}, units, cycles)
    for side in ("horowitz_joules", "library_joules"):
        assert two["frame"][side] == pytest.approx(2 * one["frame"][side], rel=1e-12)


def test_the_per_action_energies_are_independent(frames, monkeypatch):
    frame, counters, units, cycles, _ = frames["volumepro500"]
    base = accelergy.band(frame, counters, units, cycles, "cmos45")
    # The library's price moved: only its side moves.
    stored = accelergy.stored_prices()
    node = dict(stored["nodes"]["45"], add_32b_pj=2 * stored["nodes"]["45"]["add_32b_pj"])
    monkeypatch.setitem(stored["nodes"], "45", node)
    moved = accelergy.band(frame, counters, units, cycles, "cmos45")
    assert moved["units"]["interp"]["library_joules"] > base["units"]["interp"]["library_joules"]
    assert moved["frame"]["horowitz_joules"] == base["frame"]["horowitz_joules"]
    monkeypatch.undo()
    # The tables' price moved: only their side moves.
    tech = load_technology("cmos45")
    energy = dict(tech.values["energy"], add_32b_pj=2 * tech.v("energy", "add_32b_pj"))
    dearer = dataclasses.replace(tech, values={**tech.values, "energy": energy})
    monkeypatch.setattr("hwsim.energy.arch_technology", lambda arch, technology=None: dearer)
    moved = accelergy.band(frame, counters, units, cycles, "cmos45")
    assert moved["frame"]["horowitz_joules"] > base["frame"]["horowitz_joules"]
    assert moved["frame"]["library_joules"] == base["frame"]["library_joules"]


def test_the_stored_table_holds_every_builtin_shape():
    """No built-in machine at a built-in node needs the library installed."""
    shapes = {f"{w}/{b}" for w, b in accelergy._shapes()}
    nodes = accelergy.stored_prices()["nodes"]
    assert {v["technology"] for v in nodes.values()} == set(accelergy.NODES)
    for node in nodes.values():
        assert shapes <= set(node["sram"]), node["technology"]


def test_a_missing_library_is_one_line_naming_the_extra():
    code = (
        "import sys\n"
        "for m in ('hwcomponents', 'hwcomponents_library', 'hwcomponents_cacti'):\n"
        "    sys.modules[m] = None\n"
        "from hwsim.energy.accelergy import main\n"
        "raise SystemExit(main(['--out', '/nonexistent/never-written.json']))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'hwsim[energy]'" in lines[0], run.stderr


def test_a_shape_not_stored_without_the_library_names_the_extra(monkeypatch):
    def missing():
        raise NotAvailableError(accelergy._INSTALL)

    monkeypatch.setattr(accelergy, "_library", missing)
    prices = accelergy._Prices(load_technology("cmos45"))
    with pytest.raises(NotAvailableError, match=r"hwsim\[energy\]"):
        prices.sram_pj(24, 12345, "read")
    node = dataclasses.replace(load_technology("cmos45"), node_nm=130.0)
    with pytest.raises(NotAvailableError, match=r"at 130 nm \(stored: 45 nm, 250 nm, 350 nm\)"):
        accelergy._Prices(node)


@needs_library
def test_a_stored_entry_rederived_live():
    """One SRAM shape and the logic at widths other than 32 bits (the library's own width
    rules applied to the stored 32-bit prices), live at 0.35 um."""
    from hwsim.energy.accelergy import _library

    # Another version of the library may price otherwise: regenerate the table then.
    assert accelergy.library_versions() == accelergy.stored_prices()["library"]
    stored = accelergy.stored_prices()["nodes"]["350"]
    live = accelergy.live_prices(350, [(36, 147456)])
    assert live["sram"]["36/147456"] == pytest.approx(stored["sram"]["36/147456"], rel=1e-9)
    al, node = _library().aladdin, 350e-9
    adder = al.AladdinAdder(tech_node=node, width=13).add().energy * 1e12
    mult = al.AladdinMultiplier(tech_node=node, width_a=12, width_b=17).multiply().energy * 1e12
    assert adder == pytest.approx(stored["add_32b_pj"] * 13 / 32, rel=1e-9)
    assert mult == pytest.approx(stored["mult_32x32_pj"] * 12 * 17 / 1024, rel=1e-9)


def test_the_energy_command_prints_and_writes_the_band(tmp_path, capsys):
    from hwsim.cli.commands import main

    out = tmp_path / "band.json"
    argv = ["energy", "--phantom", "head:size=16", "--image", "16", "--arch", "em-cube"]
    assert main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    band = json.loads(out.read_text())
    assert band["technology"]["name"] == "cmos350"
    assert {"interp", "gradient", "classify", "shade", "composite"} <= set(band["units"])
    assert band["frame"]["ratio"] > 0
    frame_line = next(line for line in printed.splitlines() if line.startswith("frame "))
    assert f"{band['frame']['ratio']:.3g}" in frame_line


def test_a_render_that_priced_nothing_is_refused():
    scene = Scene(view=ViewSpec(width=8, height=8))
    volume = make_phantom("ball", size=8)
    run = render(scene, fidelity="functional", arch=resolve_arch("cube4"), volume=volume)
    with pytest.raises(InputError, match="counted no priced actions"):
        accelergy.band_of_run(run, resolve_arch("cube4"))


def _docs_architecture(tmp_path):
    """The architecture file of docs/architectures.md: Cube-4 with 16 pipelines and its
    own buffers, SRAM shapes the stored table does not hold."""
    import re
    from pathlib import Path

    docs = Path(__file__).resolve().parents[2] / "docs" / "architectures.md"
    (example,) = re.findall(r"```toml\n(.*?)```", docs.read_text(), flags=re.S)
    path = tmp_path / "my-cube4.toml"
    path.write_text(example)
    return path


def test_another_machine_without_the_library_is_one_line_naming_the_extra(tmp_path):
    arch = _docs_architecture(tmp_path)
    code = (
        "import sys\n"
        "for m in ('hwcomponents', 'hwcomponents_library', 'hwcomponents_cacti'):\n"
        "    sys.modules[m] = None\n"
        "from hwsim.cli.commands import main\n"
        f"raise SystemExit(main(['energy', '--arch', {str(arch)!r}, '--phantom',"
        " 'head:size=16', '--image', '16', '--quiet']))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "no stored Accelergy price" in lines[0], run.stderr
    assert "pip install 'hwsim[energy]'" in lines[0]


@needs_library
def test_another_machine_is_priced_live(tmp_path):
    from hwsim.cli.commands import main

    out = tmp_path / "band.json"
    argv = ["energy", "--arch", str(_docs_architecture(tmp_path)), "--phantom", "head:size=16"]
    assert main([*argv, "--image", "16", "--quiet", "--out", str(out)]) == 0
    band = json.loads(out.read_text())
    assert all(math.isfinite(r["ratio"]) and r["ratio"] > 0 for r in band["memories"].values())
