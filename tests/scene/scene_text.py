"""Scenes from TOML text, as the scene tests write them: ``parse`` the text of a file
``t.toml``, or take the one-line error it is refused with."""

from __future__ import annotations

import tomllib

import pytest

from hwsim.core.errors import InputError
from hwsim.spec.scene import Scene, parse_scene


def parse(text: str) -> Scene:
    return parse_scene(tomllib.loads(text), source="t.toml")


def error_of(text: str) -> str:
    """The refusal of ``text``: one line, naming the file first."""
    with pytest.raises(InputError) as info:
        parse(text)
    message = str(info.value)
    assert "\n" not in message and message.startswith("t.toml")
    return message
