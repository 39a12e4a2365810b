"""Malformed scene, architecture, technology and sweep files: each loads with values of
their declared types, or is refused in one line naming the file and a key path.

Each property starts from a valid built-in document and changes one value's type, deletes
a key or adds an unknown one (:mod:`mutate`); the loader is the one the CLI calls, in
process.  The issue's own examples are pinned as ``@example`` cases and, for every
machine, as plain cases.
"""

from __future__ import annotations

import itertools
import math
import tomllib
from pathlib import Path

import pytest
from fuzz_documents import (
    FUZZ,
    Mutation,
    check_types,
    loads_or_refuses,
    mutated,
    mutations,
    write_toml,
)
from hypothesis import example, given
from hypothesis import strategies as st

from hwsim import energy
from hwsim.core.errors import InputError
from hwsim.energy.technology import MAX_BASE_DEPTH, builtin_technologies, load_technology
from hwsim.run.fidelity import algorithms, resolve_arch
from hwsim.spec.scene import load_scene, load_transfer
from hwsim.studies.sweep.spec import load_sweep
from models.machines import families, machine_for

pytestmark = pytest.mark.fuzz

REPO = Path(__file__).resolve().parents[2]
ARCH_FILES = sorted(p for f in families() for p in f.arch_files())
#: The built-in scenes and the documented example, which has every section a scene can have.
SCENE_FILES = sorted((REPO / "hwsim" / "scenes").glob("*.toml")) + [
    REPO / "docs" / "examples" / "scene.toml"
]
TECH_FILES = sorted(builtin_technologies().values())
TECH_BASE = builtin_technologies()["cmos45"]  # gives every value itself
SWEEP_FILE = REPO / "docs" / "examples" / "sweep.toml"
_NAMES = itertools.count()


def _doc(path: Path) -> dict:
    return tomllib.loads(path.read_text())


def cases(files: list[Path]) -> st.SearchStrategy:
    """(file, mutation) pairs over ``files``."""
    return st.sampled_from(files).flatmap(lambda p: st.tuples(st.just(p), mutations(_doc(p))))


def _write(tmp_path: Path, source: Path, m: Mutation) -> Path:
    """The mutated document under a name no earlier example used (loaders cache by path)."""
    return write_toml(tmp_path, f"{source.stem}-{next(_NAMES)}.toml", mutated(_doc(source), m))


def load_arch(path: Path):
    """What ``hwsim render --arch FILE`` checks before its frame: the file, the datapath
    its formats describe, the machine that models it and its technology."""
    arch = resolve_arch(str(path))
    algorithms(arch)
    machine_for(arch)
    energy.arch_technology(arch)  # [silicon] technology, named by this file
    return arch


#: The issue's architecture examples.
ISSUE_ARCH = [
    Mutation("replace", ("formats",), 7),
    Mutation("replace", ("memory",), "fast"),
    Mutation("replace", ("buffers",), 1),
    Mutation("replace", ("published",), [1, 2]),
    Mutation("replace", ("silicon",), {"technology": 5}),
]


@FUZZ
@given(case=cases(ARCH_FILES))
@example(case=(ARCH_FILES[0], ISSUE_ARCH[0]))
@example(case=(ARCH_FILES[0], ISSUE_ARCH[1]))
@example(case=(ARCH_FILES[0], ISSUE_ARCH[2]))
@example(case=(ARCH_FILES[0], ISSUE_ARCH[3]))
def test_arch_file(tmp_path, case):
    source, m = case
    arch = loads_or_refuses(load_arch, _write(tmp_path, source, m))
    if arch is not None:
        check_types(arch)


@pytest.mark.parametrize("source", ARCH_FILES, ids=lambda p: p.stem)
@pytest.mark.parametrize("m", ISSUE_ARCH, ids=str)
def test_issue_examples_on_every_machine(tmp_path, source, m):
    with pytest.raises(InputError) as info:
        load_arch(_write(tmp_path, source, m))
    key = m.path[0]
    assert f"{key}:" in str(info.value) or f"{key}." in str(info.value)


@FUZZ
@given(case=cases(SCENE_FILES))
@example(case=(SCENE_FILES[0], Mutation("replace", ("view",), 7)))
@example(case=(SCENE_FILES[0], Mutation("replace", ("lights",), [1, 2])))
def test_scene_file(tmp_path, case):
    source, m = case
    scene = loads_or_refuses(load_scene, _write(tmp_path, source, m))
    if scene is not None:
        check_types(scene)


def _tech(path: Path):
    return load_technology(str(path))


@FUZZ
@given(case=cases(TECH_FILES))
@example(case=(TECH_BASE, Mutation("replace", ("technology",), 5)))
@example(case=(TECH_BASE, Mutation("replace", ("area", "nand2_um2", "value"), 0)))
@example(case=(TECH_BASE, Mutation("replace", ("timing", "fo4_ps", "value"), 0.0)))
@example(case=(TECH_BASE, Mutation("replace", ("technology", "base"), "fast")))
@example(case=(TECH_BASE, Mutation("replace", ("technology", "base"), "x" * 300)))
def test_technology_file(tmp_path, case):
    source, m = case
    tech = loads_or_refuses(_tech, _write(tmp_path, source, m))
    if tech is not None:
        for table in tech.values.values():
            assert all(isinstance(v, float) and math.isfinite(v) for v in table.values())
        assert tech.gate_um2(1.0) > 0 and tech.gate_level_ps > 0  # divisors


def test_technology_base_naming_itself_is_one_line(tmp_path):
    path = tmp_path / "self.toml"
    doc = _doc(TECH_FILES[0])
    doc["technology"]["base"] = "self.toml"
    write_toml(tmp_path, "self.toml", doc)
    with pytest.raises(InputError, match=r"technology.base: base chain .*self.toml -> .*self"):
        load_technology(str(path))


def test_technology_base_chain_deeper_than_the_limit(tmp_path):
    doc = _doc(TECH_FILES[0])
    for i in range(MAX_BASE_DEPTH + 2):
        doc["technology"]["base"] = f"t{i + 1}.toml"
        write_toml(tmp_path, f"t{i}.toml", doc)
    with pytest.raises(InputError, match=f"deeper than {MAX_BASE_DEPTH} files"):
        load_technology(str(tmp_path / "t0.toml"))


def _sweep(path: Path):
    return load_sweep(path)


@FUZZ
@given(m=mutations(_doc(SWEEP_FILE)))
@example(m=Mutation("replace", ("sweep", "formats"), 7))
@example(m=Mutation("replace", ("sweep", "pipelines"), [math.nan]))
def test_sweep_file(tmp_path, m):
    # Beside the example so its relative names resolve as they do for the user.
    path = write_toml(tmp_path, f"sweep-{next(_NAMES)}.toml", mutated(_doc(SWEEP_FILE), m))
    sweep = loads_or_refuses(_sweep, path)
    if sweep is not None:
        assert sweep.runs and all(isinstance(v, list) for v in sweep.axes.values())


#: A transfer-function file (``--transfer FILE``): the example scene's [transfer] table.
TRANSFER = {"schema": 1, **_doc(REPO / "docs" / "examples" / "scene.toml")["transfer"]}


@FUZZ
@given(m=mutations(TRANSFER))
@example(m=Mutation("replace", ("points",), [[1, 2]]))
@example(m=Mutation("replace", ("points", 0), "x"))
def test_transfer_file(tmp_path, m):
    path = write_toml(tmp_path, f"transfer-{next(_NAMES)}.toml", mutated(TRANSFER, m))
    spec = loads_or_refuses(load_transfer, path)
    if spec is not None:
        check_types(spec)
