"""Every built-in architecture file loads to what it loaded to before the arch-file model
(issue 33): the ArchConfig, its published figures and its memory, pinned as their reprs in
``builtin_archs.json`` (captured with the hand-written parser, commit d10f937).

A deliberate change to a built-in file changes its entry: regenerate it with
``python tests/arch/test_builtin_archs_pinned.py`` and review the diff.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from hwsim.memory import parse_memory
from hwsim.run.fidelity import builtin_archs
from hwsim.spec.published import parse_published

PINNED = Path(__file__).with_name("builtin_archs.json")


def snapshot() -> dict[str, dict[str, str]]:
    """Each built-in machine as the reprs of what its file loads to (its path left out)."""
    out = {}
    for name, arch in builtin_archs().items():
        figures = parse_published(
            arch.published, source=arch.source, peak_samples_per_second=arch.peak_samples_per_second
        )
        out[name] = {
            "arch": repr(dataclasses.replace(arch, source="<built-in>")),
            "published": repr(figures),
            "memory": repr(parse_memory(arch.memory, source=arch.source)),
        }
    return out


@pytest.fixture(scope="module")
def loaded() -> dict[str, dict[str, str]]:
    return snapshot()


def test_the_built_in_machines_are_the_pinned_ones(loaded):
    assert sorted(loaded) == sorted(json.loads(PINNED.read_text()))


@pytest.mark.parametrize("name", sorted(json.loads(PINNED.read_text())))
@pytest.mark.parametrize("part", ["arch", "published", "memory"])
def test_a_built_in_file_loads_as_pinned(loaded, name, part):
    assert loaded[name][part] == json.loads(PINNED.read_text())[name][part]


if __name__ == "__main__":
    PINNED.write_text(json.dumps(snapshot(), indent=1, sort_keys=True) + "\n")
