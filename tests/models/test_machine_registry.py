"""The machine registry: every rung finds a machine through it, and a new family is its
package plus one registration (here a toy family registered from the test suite)."""

from __future__ import annotations

import pytest

from hwsim.cli.commands import main
from hwsim.core.errors import NotAvailableError
from hwsim.run.fidelity import builtin_archs, machine_rungs, render, resolve_arch
from models.functional import render_functional
from models.machines import FAMILIES, Machine, families, machine_for, register, unregister
from models.machines.common.results import CycleResult

pytestmark = pytest.mark.model

TOY_ARCH = """
schema = 1
name = "toy"
description = "a toy ray machine: the functional image, one sample per clock"

[pipeline]
family = "toyray"
order = "ray"
count = 2
clock_hz = 1e6

[features]
perspective = true
"""


def _toy_cycle(backend, *, faults, trace, progress, steady_state=False):
    """One clock per sample per pipeline: the simplest machine that is not a copy."""
    be = backend
    image = render_functional(be.frame)
    cycles = -(-image.samples // be.arch.pipelines)
    counters = {"toy.samples": image.samples}
    return CycleResult(image.image, image.samples, image.rays, cycles, counters)


TOY = Machine(name="toyray", orders=("ray",), cycle=_toy_cycle, transaction=None)


@pytest.fixture
def toy(tmp_path):
    path = tmp_path / "toy.toml"
    path.write_text(TOY_ARCH)
    register(TOY)
    yield str(path)
    unregister(TOY)


def test_builtin_families_serve_every_builtin_machine():
    names = [m.name for m in families()]
    assert names[:3] == ["cube4", "volumepro", "vizard2"]
    assert names == [module.split(".")[-2] for module in FAMILIES]  # registry order
    for arch in builtin_archs().values():
        machine = machine_for(arch)
        assert arch.family == machine.name and arch.order in machine.orders
        assert arch.source.replace("\\", "/").endswith(
            f"models/machines/{machine.name}/{arch.name}.toml"
        )


def test_a_toy_family_renders_through_every_entry_point(toy, tmp_path, capsys):
    arch = resolve_arch(toy)
    assert machine_for(arch) is TOY
    assert machine_rungs(arch) == ["golden", "functional", "cycle"]
    run = render(_scene(), fidelity="cycle", arch=arch)
    functional = render(_scene(), fidelity="functional", arch=arch)
    assert (run.image == functional.image).all()
    assert run.cycles == -(-functional.samples // 2) and run.counters["toy.samples"] > 0
    with pytest.raises(NotAvailableError, match="toyray family.*transaction"):
        render(_scene(), fidelity="transaction", arch=arch)
    out = tmp_path / "o"
    assert main(["render", "--phantom", "ball:size=8", "--image", "8", "--fidelity", "cycle",
                 "--arch", toy, "--out", str(out), "--quiet"]) == 0  # fmt: skip
    # The built-in ray machine is untouched: vizard2 names its family.
    assert machine_for(resolve_arch("vizard2")).name == "vizard2"


def test_an_unknown_family_is_refused_naming_the_registered_ones(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(TOY_ARCH.replace('family = "toyray"', 'family = "nosuch"'))
    with pytest.raises(NotAvailableError, match="nosuch.*allowed: cube4, volumepro, vizard2"):
        machine_for(resolve_arch(str(path)))
    assert machine_rungs(resolve_arch(str(path))) == ["golden", "functional"]


def _scene():
    import dataclasses

    from hwsim.spec.scene import VolumeSpec, load_scene

    base = load_scene("head")
    view = dataclasses.replace(base.view, width=12, height=12)
    return base.replace(volume=VolumeSpec(phantom="ball", params=(("size", 10),)), view=view)


@pytest.mark.parametrize(
    "name", [n for n, cfg in builtin_archs().items() if "rtl" not in machine_rungs(cfg)]
)
def test_the_rtl_rung_never_lends_one_machines_top_to_another(name, monkeypatch):
    """A family without an RTL top is refused at the rtl rung by name, before any top is
    built: Cube-1 is slice-parallel like Cube-4, and its frames once reached the Cube-4 top."""
    import rtl.rung

    def built(*args, **kwargs):
        raise AssertionError(f"{name}: an RTL top was built for a machine that has none")

    monkeypatch.setattr(rtl.rung, "render_rtl", built)
    from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec, VolumeSpec

    scene = Scene(
        volume=VolumeSpec(phantom="head", params=(("size", 16),)),
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=0, elevation=0, width=16, height=16),
        render=RenderSpec(mode="composite"),
    )
    with pytest.raises(NotAvailableError, match=f"{name} has no RTL top"):
        render(scene, fidelity="rtl", arch=name)
