"""The memory budget: sizes parsed, refusals named, the CLI flag honoured."""

from __future__ import annotations

import os

import pytest

from hwsim.cli.commands import main
from hwsim.core import budget
from hwsim.core.errors import InputError


@pytest.fixture(autouse=True)
def _no_override(monkeypatch):
    monkeypatch.delenv(budget.ENV_VAR, raising=False)
    yield
    budget.set_memory_budget(None)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("2G", 2 << 30),
        ("512M", 512 << 20),
        ("1.5GiB", 3 << 29),
        ("1048576", 1 << 20),
        ("3 mb", 3 << 20),
    ],
)
def test_sizes_parse_in_binary_units(text, expected):
    assert budget.parse_size(text) == expected


@pytest.mark.parametrize("text", ["", "lots", "-1G", "2X", "1K"])
def test_bad_sizes_name_the_key(text):
    with pytest.raises(InputError, match="--max-memory"):
        budget.parse_size(text)


def test_default_is_a_fraction_of_available_memory():
    expected = int(budget.available_memory_bytes() * budget.DEFAULT_FRACTION)
    assert budget.memory_budget() == expected > 0


def test_environment_then_override(monkeypatch):
    monkeypatch.setenv(budget.ENV_VAR, "64M")
    assert budget.memory_budget() == 64 << 20
    budget.set_memory_budget(8 << 20)
    assert budget.memory_budget() == 8 << 20


def test_require_fits_refuses_with_both_sizes():
    budget.set_memory_budget(1 << 20)
    budget.require_fits(1 << 20, what="x")  # exactly the budget fits
    with pytest.raises(InputError) as info:
        budget.require_fits(3 << 30, what="voxel data", source="big.nii", key="dim")
    text = str(info.value)
    assert text.startswith("big.nii: dim: voxel data needs 3.0 GiB")
    assert "1.0 MiB" in text and "--max-memory" in text


def test_cli_flag_is_validated(capsys):
    assert main(["render", "--max-memory", "lots", "--out", "/nonexistent/x"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--max-memory" in err


def test_a_cli_budget_ends_with_its_command(tmp_path, capsys):
    """--max-memory bounds its own command (and the workers it starts), not the next call
    in the same process: the suite's in-process CLI calls leaked 64M into later tests."""
    small = ["render", "--phantom", "ball:size=8", "--image", "256", "--quiet"]
    assert main([*small, "--max-memory", "1M", "--out", str(tmp_path / "a")]) == 2
    assert "memory budget of 1.0 MiB" in capsys.readouterr().err
    assert budget.ENV_VAR not in os.environ
    assert budget._override is None
    assert main([*small, "--out", str(tmp_path / "b")]) == 0
