"""House style is checked with the suite: ruff's explicit rule list must pass on the tree,
and no function in hwsim/ is longer than :data:`MAX_FUNCTION_LINES` (docs/conventions.md
item 9: functions under ~80 lines)."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: The longest function allowed in hwsim/, from its ``def`` line to its body's last line.
MAX_FUNCTION_LINES = 80


def test_ruff_check_passes():
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.fail("ruff is not installed (it is a test dependency: pip install -e '.[test]')")
    proc = subprocess.run(
        [ruff, "check", "--no-cache", str(REPO)], capture_output=True, text=True, cwd=REPO
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int, int]]:
    """``(name, first line, lines)`` of every function (nested ones too) in ``source``
    longer than ``limit`` lines, counted from the ``def`` line to the last line of its body
    (decorators not counted)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines = node.end_lineno - node.lineno + 1
            if lines > limit:
                found.append((node.name, node.lineno, lines))
    return found


def test_the_length_check_finds_a_long_function():
    body = "\n".join(f"    x{k} = {k}" for k in range(79))
    source = f"@decorator\ndef short():\n{body}\n\n\nasync def long():\n{body}\n    return 1\n"
    assert long_functions(source) == [("long", 84, 81)]  # "short" has 80: allowed


def test_no_function_in_hwsim_is_longer_than_80_lines():
    too_long = [
        f"{path.relative_to(REPO)}:{line} {name} ({lines} lines)"
        for path in sorted((REPO / "hwsim").rglob("*.py"))
        for name, line, lines in long_functions(path.read_text(encoding="utf-8"))
    ]
    assert not too_long, f"longer than {MAX_FUNCTION_LINES} lines (split them): " + ", ".join(
        too_long
    )
