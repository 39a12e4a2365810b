"""The transfer function from the command line and the API: the default scene's ``auto``
preset chooses from the data and says why (summary line, stats.json), and ``--transfer
PRESET|FILE`` overrides it (issue 32)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import hwsim
from hwsim.cli.commands import main
from hwsim.spec.scene import load_scene

pytestmark = pytest.mark.system

HEAD_TOML = Path(hwsim.__file__).parent / "scenes" / "head.toml"


def render(capsys, out: Path, *args: str) -> tuple[str, dict, bytes]:
    """``hwsim render ... --image 48 --out OUT``: its summary, stats and image bytes."""
    assert main(["render", *args, "--image", "48", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    stats = json.loads((out / "stats.json").read_text())
    return text, stats, (out / "image.npy").read_bytes()


def named_scene(tmp_path: Path, volume: Path, preset: str) -> Path:
    """The built-in head scene with ``volume`` and ``preset = PRESET`` written out."""
    text = HEAD_TOML.read_text()
    assert 'phantom = "head"\nparams = { size = 128 }' in text and 'preset = "auto"' in text
    text = text.replace('phantom = "head"\nparams = { size = 128 }', f'path = "{volume}"')
    text = text.replace('preset = "auto"', f'preset = "{preset}"')
    path = tmp_path / f"named-{preset}.toml"
    path.write_text(text)
    return path


def test_default_scene_chooses_mr_for_the_mr_volume(shared_data, tmp_path, capsys):
    mr = shared_data / "mr_brainsmall.nrrd"
    text, stats, image = render(capsys, tmp_path / "auto", "--volume", str(mr))
    assert "transfer: mr (auto: NRRD header comment MR)" in text
    assert stats["transfer"] == {"preset": "mr", "chosen_by": "auto: NRRD header comment MR"}
    assert stats["scene"]["transfer"]["preset"] == "mr"
    scene = named_scene(tmp_path, mr, "mr")
    text, named_stats, named = render(capsys, tmp_path / "named", str(scene))
    assert "transfer: mr (scene)" in text
    assert named_stats["transfer"] == {"preset": "mr", "chosen_by": "scene"}
    assert named == image  # byte-identical image.npy
    _, _, flagged = render(capsys, tmp_path / "flag", "--volume", str(mr), "--transfer", "mr")
    assert flagged == image
    # and the choice matters: the ct preset draws another image
    _, _, ct = render(capsys, tmp_path / "ct", "--volume", str(mr), "--transfer", "ct")
    assert ct != image


def test_default_scene_still_chooses_ct_for_ct(shared_data, tmp_path, capsys):
    text, stats, _ = render(
        capsys, tmp_path / "ct", "--volume", str(shared_data / "ct_cranium.nrrd")
    )
    assert "transfer: ct (auto: NRRD header comment CT)" in text
    assert stats["transfer"]["preset"] == "ct"


def test_head_phantom_image_is_the_ct_presets(tmp_path, capsys):
    """The built-in scenes no longer name ct: auto gives their phantom the same image."""
    text, stats, auto = render(capsys, tmp_path / "auto", "--phantom", "head:size=32")
    assert "transfer: ct (auto: volume units HU)" in text
    _, _, named = render(capsys, tmp_path / "ct", "--phantom", "head:size=32", "--transfer", "ct")
    assert named == auto


def test_transfer_file_toml_and_npy(tmp_path, capsys):
    table = tmp_path / "grey.npy"
    np.save(table, np.linspace([0, 0, 0, 0], [1, 1, 1, 0.5], 16))
    toml = tmp_path / "tf.toml"
    toml.write_text('schema = 1\ndescription = "grey"\ntable = "grey.npy"\n')
    text, stats, from_toml = render(
        capsys, tmp_path / "toml", "--phantom", "head:size=24", "--transfer", str(toml)
    )
    assert "transfer: scene transfer.table" in text
    assert stats["transfer"] == {"preset": None, "chosen_by": "scene transfer.table"}
    _, _, from_npy = render(
        capsys, tmp_path / "npy", "--phantom", "head:size=24", "--transfer", str(table)
    )
    assert from_npy == from_toml
    points = tmp_path / "points.toml"
    points.write_text("points = [[-1024, 0, 0, 0, 0], [2000, 1, 1, 1, 0.5]]\n")
    spec = hwsim.load_scene("head", transfer=points).transfer
    assert spec.points == ((-1024, 0, 0, 0, 0), (2000, 1, 1, 1, 0.5)) and spec.preset is None


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("bogus", "--transfer: unknown preset 'bogus' (allowed: auto, ct, mr, ramp, warm,"),
        ("missing.toml", "--transfer: file not found (allowed: auto, ct, mr"),
        ("image.png", "--transfer: unknown preset 'image.png'"),
    ],
)
@pytest.mark.parametrize("command", [["render"], ["rtl", "diff"]])
def test_bad_transfer_is_one_line(tmp_path, capsys, command, value, message):
    out = ["--out", str(tmp_path)] if command == ["render"] else []
    status = main([*command, "--transfer", value, *out])
    err = capsys.readouterr().err
    assert status == 2 and message in err and err.count("\n") == 1


def test_bad_transfer_file_names_its_key(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('preset = "mr"\nopacity = 1\n')
    assert main(["render", "--transfer", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert f"{bad}: opacity: unknown key" in capsys.readouterr().err


def test_classification_scene_refuses_transfer(capsys, tmp_path):
    assert main(["render", "head-vp1000", "--transfer", "ct", "--out", str(tmp_path)]) == 2
    assert "--transfer: the scene's [classification] LUTs" in capsys.readouterr().err


def test_api_transfer_keyword():
    assert hwsim.load_scene(transfer="mr").transfer.preset == "mr"
    assert load_scene().transfer.preset == "auto"  # the default scene names no preset
    with pytest.raises(hwsim.InputError, match="^transfer: unknown preset .nope."):
        hwsim.load_scene(transfer="nope")
    with pytest.raises(hwsim.InputError, match="transfer: expected a string"):
        hwsim.load_scene(transfer=3)
