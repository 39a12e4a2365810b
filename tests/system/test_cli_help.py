"""``hwsim --help`` is written for users: every option of every command says what it does,
the top level opens with a description and the commands, and points to the docs."""

from __future__ import annotations

import argparse

import pytest

from hwsim.cli.commands import build_parser, main
from hwsim.cli.parser import DESCRIPTION

pytestmark = pytest.mark.system

#: Words of a developer's docstring, not of a user's description.
DEVELOPER_WORDS = ("parse", "library", "libraries", "thin", "shell", "module", "docstring")


def walk(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("hwsim",)):
    """(command path, parser) for ``parser`` and every subcommand below it."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from walk(child, (*path, name))


def subcommand_actions(parser: argparse.ArgumentParser):
    return [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]


def test_the_walk_reaches_every_command_and_the_rtl_subcommands():
    paths = {" ".join(path) for path, _ in walk(build_parser())}
    assert {"hwsim render", "hwsim sweep", "hwsim bench", "hwsim rtl"} <= paths
    assert {"hwsim rtl build", "hwsim rtl diff"} <= paths


def test_every_option_of_every_command_has_help_text():
    missing = [
        f"{' '.join(path)} {'/'.join(action.option_strings) or action.dest}"
        for path, parser in walk(build_parser())
        for action in parser._actions
        if not isinstance(action, argparse._SubParsersAction)
        and (action.help is None or not str(action.help).strip())
    ]
    assert missing == []


def test_every_command_has_a_one_line_help():
    missing = [
        f"{' '.join(path)} {choice.dest}"
        for path, parser in walk(build_parser())
        for action in subcommand_actions(parser)
        for choice in action._choices_actions
        if not (choice.help or "").strip()
    ]
    assert missing == []


def help_text(argv: list[str], capsys) -> str:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 0
    return capsys.readouterr().out


def test_the_top_level_help_opens_for_users_and_points_to_the_docs(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "100")
    text = help_text(["--help"], capsys)
    usage, description, *rest = [block for block in text.split("\n\n") if block.strip()]
    assert usage.startswith("usage: hwsim")
    assert description == DESCRIPTION and "\n" not in description
    for first_line in (text.splitlines()[0], description):
        assert not [w for w in DEVELOPER_WORDS if w in first_line.lower()], first_line
    commands = text.split("\ncommands:\n", 1)[1]
    (sub,) = subcommand_actions(build_parser())
    for choice in sub._choices_actions:  # one line each: name and its help
        assert f"    {choice.dest:<12} {choice.help}\n" in commands
    epilog = rest[-1]
    assert "README.md" in epilog and "docs/cli.md" in epilog


def test_a_command_help_shows_choices_and_defaults(capsys):
    text = " ".join(help_text(["render", "--help"], capsys).split())
    assert "--fidelity {golden,functional,transaction,cycle,rtl}" in text
    assert "(default: golden; docs/fidelity.md)" in text
    assert "--mode {composite,mip,minip,xray,iso}" in text


@pytest.mark.parametrize(
    ("argv", "count"),
    [
        (["scenes"], 0),
        (["-v", "scenes"], 1),
        (["scenes", "-vv"], 2),
        (["--verbose", "sweep", "s.toml"], 1),
        (["rtl", "build", "--out", "x", "-v"], 1),
        (["rtl", "-v", "diff"], 1),
    ],
)
def test_verbose_counts_before_or_after_the_command(argv, count):
    assert build_parser().parse_args(argv).verbose == count
