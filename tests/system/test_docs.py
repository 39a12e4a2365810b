"""Examples in the docs are run: TOML blocks parse, shell examples succeed."""

from __future__ import annotations

import re
import shlex
import tomllib
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.spec.scene import load_transfer, parse_scene

DOCS = Path(__file__).resolve().parents[2] / "docs"
pytestmark = pytest.mark.system


def blocks(doc: str, lang: str) -> list[str]:
    text = (DOCS / doc).read_text()
    return re.findall(rf"```{lang}\n(.*?)```", text, flags=re.S)


def test_scene_reference_example_is_a_valid_scene():
    example, _transfer_file = blocks("scenes.md", "toml")
    scene = parse_scene(tomllib.loads(example), source="docs/scenes.md")
    assert scene.name == "skull" and scene.cut_planes and scene.crop is not None


def test_transfer_file_example_is_a_valid_transfer_file(tmp_path):
    _scene, example = blocks("scenes.md", "toml")
    path = tmp_path / "bone.toml"
    path.write_text(example)
    spec = load_transfer(path)
    assert spec.preset is None and len(spec.points) == 3 and spec.order == "post"


def test_cli_examples_run(tmp_path):
    commands = [
        line
        for block in blocks("cli.md", "sh")
        for line in block.splitlines()
        if line.startswith("hwsim ")
    ]
    assert len(commands) >= 3
    for line in commands:
        argv = shlex.split(line)[1:]
        argv[argv.index("--out") + 1] = str(tmp_path / argv[argv.index("--out") + 1])
        assert main([*argv, "--quiet"]) == 0, line


def test_architecture_reference_example_renders_at_cycle_fidelity(tmp_path):
    (example,) = blocks("architectures.md", "toml")
    arch = tmp_path / "my-cube4.toml"
    arch.write_text(example)
    args = ["render", "--arch", str(arch), "--fidelity", "cycle", "--phantom", "head:size=16"]
    assert main([*args, "--image", "16", "--out", str(tmp_path / "o"), "--quiet"]) == 0
