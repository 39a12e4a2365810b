"""Every built-in scene and every documented example scene loads to the values it loaded to
before the scene file moved onto its msgspec model (issue 33): ``loaded_scenes.json`` was
written by the Table-based loader, each scene as ``dataclasses.asdict``.  The comparison is
of JSON text, so an int where a float was (``1`` for ``1.0``) fails too.

A deliberate change to a built-in scene or a documented example rewrites its entry (the
same ``dataclasses.asdict`` of what :func:`loaded` returns, ``json.dump(..., indent=1,
sort_keys=True)``).
"""

from __future__ import annotations

import dataclasses
import json
import re
import tomllib
from pathlib import Path

import pytest

from hwsim.spec.scene import builtin_scenes, load_scene, load_transfer, parse_scene

REPO = Path(__file__).resolve().parents[2]
EXPECTED = json.loads((Path(__file__).parent / "loaded_scenes.json").read_text())
_MD = (REPO / "docs" / "scenes.md").read_text()


def _md_scene(pattern: str):
    text = "".join(re.findall(pattern, _MD, flags=re.S))
    return parse_scene(tomllib.loads(text), source="docs/scenes.md")


def loaded(key: str, tmp_path: Path):
    """What the loader makes of the document ``key`` names."""
    if key.startswith("hwsim/scenes/"):
        return load_scene(Path(key).stem)
    if key == "docs/examples/scene.toml":
        return dataclasses.replace(load_scene(REPO / key), source=key)
    example, transfer = re.findall(r"```toml\n(.*?)```", _MD, flags=re.S)
    if key.endswith("complete example"):
        return parse_scene(tomllib.loads(example), source="docs/scenes.md")
    if key.endswith("transfer file"):
        (tmp_path / "bone.toml").write_text(transfer)
        return load_transfer(tmp_path / "bone.toml")
    return _md_scene(r"```toml (?:classification|geometry|cursor)\n(.*?)```")


def test_every_builtin_scene_is_in_the_snapshot():
    assert {f"hwsim/scenes/{name}.toml" for name in builtin_scenes()} <= set(EXPECTED)
    assert len(EXPECTED) == len(builtin_scenes()) + 4


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_document_loads_to_its_snapshot(key, tmp_path):
    got = json.dumps(dataclasses.asdict(loaded(key, tmp_path)), sort_keys=True)
    assert got == json.dumps(EXPECTED[key], sort_keys=True)
