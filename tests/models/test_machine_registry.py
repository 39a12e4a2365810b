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
