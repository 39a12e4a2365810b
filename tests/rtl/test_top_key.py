# amaranth: UnusedElaboratable=no
"""The RTL top's build key (rtl/top_key.py, rtl/rung.py) follows everything that reaches
its Verilog: a constant or a model file the generator imports changes the build folder, a
file it does not import leaves it alone.  No Verilog is written (the key is computed
before any build): each test takes under a second, the fresh-process one a few."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

import rtl.shade
import rtl.top
from models.datapath import Datapath
from models.units.composite import CompositeConfig
from rtl import rung, top_key
from rtl.top_layouts import TopGeometry

pytestmark = pytest.mark.rtl
REPO = Path(__file__).resolve().parents[2]
DP, GEO = Datapath(), TopGeometry(2, 16)


def _folder(dp=DP, geo=GEO) -> str:
    """The Verilator build folder's name (``build_dir`` needs the program's dp and geo)."""
    return rung.build_dir(SimpleNamespace(dp=dp, geo=geo), "verilator", Path("/b")).name


def test_a_constant_the_verilog_uses_changes_the_build_folder(monkeypatch):
    before = _folder()
    assert len(rtl.top.Cube4Top(DP, GEO).ka) == rtl.top.COEF_BITS
    monkeypatch.setattr(rtl.top, "COEF_BITS", rtl.top.COEF_BITS - 2)
    assert len(rtl.top.Cube4Top(DP, GEO).ka) == rtl.top.COEF_BITS  # it reaches a port
    coef = _folder()
    monkeypatch.setattr(rtl.shade, "LATENCY", rtl.shade.LATENCY + 1)  # the shader's stages
    latency = _folder()
    assert len({before, coef, latency}) == 3
    monkeypatch.undo()
    assert _folder() == before  # the same values, the same build


def test_the_configuration_changes_the_build_folder():
    folders = {
        _folder(),
        _folder(geo=TopGeometry(2, 32)),
        _folder(dp=Datapath(voxel_bits=8)),
        _folder(dp=Datapath(composite=CompositeConfig(acc_frac_bits=14))),
    }
    assert len(folders) == 4


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    """A copy of the repository's Python packages, to edit."""
    root = tmp_path_factory.mktemp("tree")
    for package in ("rtl", "models", "hwsim"):
        shutil.copytree(
            REPO / package,
            root / package,
            ignore=lambda _, names: [
                n for n in names if not n.endswith(".py") and "." in n or n == "__pycache__"
            ],
        )
    return root


@pytest.mark.parametrize(
    ("path", "old", "new", "rebuilds"),
    [
        # reach the Verilog: a unit's stage plan and format, the datapath, a number format
        ("rtl/shade.py", "DIVIDE_STAGES = 4", "DIVIDE_STAGES = 3", True),
        ("models/units/composite.py", "_ALPHA_BITS = 12", "_ALPHA_BITS = 11", True),
        ("models/datapath.py", "voxel_bits: int = 12", "voxel_bits: int = 10", True),
        (
            "hwsim/numerics/format.py",
            'rounding: str = "nearest-up"',
            'rounding: str = "floor"',
            True,
        ),
        # a comment in the generator's closure: rebuilds (the key reads sources, not Verilog)
        ("rtl/top.py", "\nfrom __future__", "\n# a comment\nfrom __future__", True),
        # files the generator does not import: the same build
        ("rtl/frame.py", "\nfrom __future__", "\n# a comment\nfrom __future__", False),
        ("rtl/rung.py", "_BINARIES = {", "_UNUSED = 1\n_BINARIES = {", False),
        ("models/machines/cube4/timing.py", "\nfrom __future__", "\nX = 1\nfrom __future__", False),
        ("hwsim/cli/commands.py", "\nfrom __future__", "\n# a comment\nfrom __future__", False),
    ],
)
def test_an_edit_rebuilds_if_the_generator_imports_the_file(tree, path, old, new, rebuilds):
    before = top_key.verilog_key(DP, GEO, root=tree)
    file = tree / path
    text = file.read_text()
    assert text.count(old) == 1
    file.write_text(text.replace(old, new))
    try:
        assert (top_key.verilog_key(DP, GEO, root=tree) != before) == rebuilds
    finally:
        file.write_text(text)
    assert top_key.verilog_key(DP, GEO, root=tree) == before


def test_a_new_import_brings_its_module_into_the_key(tree):
    """A function-local import the generator gains is followed: no list to keep."""
    file = tree / "models/units/shade.py"
    text = file.read_text()
    before = top_key.verilog_key(DP, GEO, root=tree)
    assert "hwsim.report" not in top_key.generator_sources(tree)
    file.write_text(text + "\n\ndef _later():\n    import hwsim.report  # noqa: F401\n")
    try:
        assert "hwsim.report" in top_key.generator_sources(tree)
        assert top_key.verilog_key(DP, GEO, root=tree) != before
    finally:
        file.write_text(text)


def test_a_module_is_hashed_as_this_process_imported_it(monkeypatch):
    """A file edited while a process runs: the process keys the code it runs."""
    assert {"rtl.top", "rtl.top_bench", "models.units.shade"} <= set(top_key._IMPORTED)
    before = _folder()
    edited = top_key._IMPORTED["models.units.shade"] + b"\nLATENCY = 5\n"
    monkeypatch.setitem(top_key._IMPORTED, "models.units.shade", edited)
    assert _folder() != before


_FRESH = """
import json, sys
from pathlib import Path
from amaranth.hdl import Fragment
from models.datapath import Datapath
from rtl.top import Cube4Top
from rtl.top_bench import bench_verilog, icarus_testbench, verilator_main
from rtl.top_layouts import TopGeometry
repo = Path(sys.argv[1])
def ours():
    return sorted(
        name for name, m in sys.modules.items()
        if getattr(m, "__file__", None) and Path(m.__file__).resolve().is_relative_to(repo)
        and ".venv" not in m.__file__
    )
imported = ours()
top = Cube4Top(Datapath(), TopGeometry(2, 8))
Fragment.get(top, None)  # elaborate: what the export runs
bench_verilog(top), icarus_testbench(), verilator_main()
elaborated = ours()
from rtl import top_key
key = top_key.verilog_key(Datapath(), TopGeometry(2, 16))
print(json.dumps({"imported": imported, "elaborated": elaborated, "key": key}))
"""


def test_the_closure_holds_what_the_generator_loads_and_the_key_is_every_process_s():
    """In a fresh interpreter: importing the generator loads exactly the modules marked
    ``at_import``; elaborating a top and writing its bench loads none outside the closure;
    the key there equals this process's (which has imported much more)."""
    import hwsim.spec.published  # noqa: F401  (lazily reached by the closure: must not matter)

    done = subprocess.run(
        [sys.executable, "-c", _FRESH, str(REPO)],
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
    )
    fresh = json.loads(done.stdout.strip().splitlines()[-1])
    sources = top_key.generator_sources()
    eager = {name for name, (_, at_import) in sources.items() if at_import}
    assert set(fresh["imported"]) == eager
    assert set(fresh["elaborated"]) <= set(sources)
    assert fresh["key"] == top_key.verilog_key(DP, GEO)
