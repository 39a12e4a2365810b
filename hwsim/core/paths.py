"""Output paths: checked before any work starts, and recorded without the machine's paths.

Every command resolves, creates and tests each output folder and file it was given
before it loads or renders anything, so an unwritable ``--out``, ``--trace`` or ``--db``
is a one-line input error (exit status 2) up front, never a crash after minutes of
simulation.

A path an output records (``stats.json``, figures, benchmark JSON, sweep rows, the
report) is written by :func:`display_path`: relative to the run folder when inside it,
else to the repository (``../shared/...`` for its siblings), else to the working folder,
else as given; free text such as an error message goes through :func:`display_text`.
The tool keeps its resolved absolute paths for reading and for cache keys.
"""

from __future__ import annotations

import ast
import errno
import os
import re
import stat
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from functools import cache
from pathlib import Path

from hwsim.core.errors import InputError

__all__ = [
    "output_folder",
    "output_file",
    "os_error",
    "os_problem",
    "file_kind",
    "input_file",
    "repo_root",
    "display_path",
    "display_text",
    "locate",
    "FILE",
    "FOLDER",
    "plan_outputs",
    "in_folder",
    "atomic_write",
    "write_text_atomic",
    "naming",
    "recording_reads",
    "reads",
]


def output_folder(out_dir: str | Path, key: str = "--out") -> Path:
    """Create ``out_dir`` and check it is writable (bad input, exit 2, if not).

    Every command calls this for each of its output folders before any work starts, so
    an unwritable output is refused up front and never after minutes of simulation.
    """
    out = Path(out_dir)
    kind = file_kind(out, key)
    if kind is not None and kind != "a folder":
        raise InputError(f"exists and is not a folder ({kind})", source=str(out), key=key)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"cannot create output folder: {_what(exc)}", source=str(exc.filename or out), key=key
        ) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError("output folder is not writable", source=str(out), key=key)
    return out


def output_file(path: str | Path, key: str) -> Path:
    """Create the folder of the output file ``path`` and check the file can be written."""
    target = Path(path)
    kind = file_kind(target, key)
    if kind == "a folder":
        raise InputError("is a folder, expected a file name", source=str(target), key=key)
    if kind not in (None, "a file"):  # opening a FIFO to write waits for a reader
        raise InputError(
            f"is {kind}, not a regular file", source=str(target), key=key, allowed="a file name"
        )
    output_folder(target.parent if str(target.parent) else Path("."), key=key)
    if kind is not None and not os.access(target, os.W_OK):
        raise InputError("output file is not writable", source=str(target), key=key)
    return target


# ------------------------------------------------------------------ inputs and OS errors

#: What :func:`file_kind` calls each kind of file-system entry.
_KINDS = {
    stat.S_IFREG: "a file",
    stat.S_IFDIR: "a folder",
    stat.S_IFIFO: "a named pipe (FIFO)",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
    stat.S_IFLNK: "a symbolic link",
}


def _what(exc: OSError) -> str:
    """What went wrong, in the operating system's words: ``file name too long``."""
    text = exc.strerror or str(exc) or type(exc).__name__
    return text[:1].lower() + text[1:]


def os_error(exc: OSError, key: str | None = None) -> InputError:
    """The one-line :class:`InputError` for an operating-system error: the path it names
    and what went wrong (``PATH: file name too long``).  The command line's error
    boundary (``hwsim.cli.commands.main``) turns every escaping ``OSError`` into this."""
    names = [n for n in (exc.filename, exc.filename2) if n is not None]
    source = " -> ".join(os.fsdecode(n) if isinstance(n, bytes) else str(n) for n in names)
    allowed = "names of at most 255 bytes" if exc.errno == errno.ENAMETOOLONG else None
    return InputError(_what(exc), source=source or None, key=key, allowed=allowed)


def os_problem(exc: BaseException) -> InputError | None:
    """The one-line error for an exception the operating system caused, else None (a bug).

    An ``OSError`` (name too long, permission denied, no space, not found, a symlink
    loop, ...) and Python 3.11's ``RuntimeError("Symlink loop from '...'")`` of
    ``Path.resolve`` are the user's to fix: :func:`os_error`.
    """
    if isinstance(exc, OSError):
        return os_error(exc)
    text = str(exc) if isinstance(exc, RuntimeError) else ""
    if text.startswith("Symlink loop from "):
        name = text.removeprefix("Symlink loop from ")
        with suppress(ValueError, SyntaxError):
            name = str(ast.literal_eval(name))
        return InputError("too many levels of symbolic links (a symlink loop)", source=name)
    return None


def file_kind(path: str | Path, key: str | None = None) -> str | None:
    """What ``path`` is (``"a file"``, ``"a folder"``, ``"a named pipe (FIFO)"``, ...), or
    None when nothing is there; a name too long, a symlink loop, a folder that cannot be
    searched and the like are a one-line :class:`InputError`."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        raise os_error(exc, key) from None
    except ValueError:  # an embedded NUL character
        raise InputError("path holds a NUL character", source=repr(str(path)), key=key) from None
    return _KINDS.get(stat.S_IFMT(mode), "not a regular file")


def input_file(path: str | Path, key: str | None = None, *, folder: bool = False) -> Path:
    """``path`` as a :class:`Path`, checked before any reader opens it: it exists and is a
    regular file (or a folder, with ``folder=True``).

    A named pipe would block ``open`` until a writer comes, a device (``/dev/zero``) reads
    without end and a socket cannot be opened at all, so each is refused by what it is,
    as is a missing file, a name too long or a symlink loop: one line naming the path.
    Every reader of a user's file (volumes, scenes, architectures, technologies, sweeps,
    transfer tables, report inputs) opens it only after this.
    """
    target = Path(path)
    kind = file_kind(target, key)
    if kind is None:
        raise InputError("file not found", source=str(target), key=key)
    if kind == "a file" or (folder and kind == "a folder"):
        _note_read(target, key)
        return target
    expected = "a file or a folder" if folder else "a file"
    raise InputError(f"is {kind}, expected {expected}", source=str(target), key=key)


# ------------------------------------------------------------------ the files a command read

#: Every file :func:`input_file` passed while :func:`recording_reads` is active (the
#: command line records a whole command): (key, path) by path.  One dict for the process,
#: not a context variable, so that a file a frame thread reads is counted too.
_READS: dict[str, tuple[str, Path]] | None = None


def _note_read(path: Path, key: str | None) -> None:
    found = _READS
    if found is not None:
        found.setdefault(os.path.abspath(path), (key or "read", path))


@contextmanager
def recording_reads() -> Iterator[None]:
    """Inside the block, every file a reader opens (each one calls :func:`input_file`
    first: scenes, architectures, technologies and their ``base`` files, transfer
    files and tables, volumes, sweeps, report inputs) is recorded: :func:`plan_outputs`
    counts them as inputs and :func:`atomic_write` never replaces one.  So a file named
    only inside another (a technology path in an architecture file) is an input by
    construction, not by a list kept per command."""
    global _READS
    if _READS is not None:  # nested (an API call inside a command): one record
        yield
        return
    _READS = {}
    try:
        yield
    finally:
        _READS = None


def reads() -> list[tuple[str, Path]]:
    """The files read so far inside :func:`recording_reads`, as (key, path)."""
    return list((_READS or {}).values())


@cache
def repo_root() -> Path | None:
    """The repository holding this package (the folder with ``pyproject.toml`` above
    ``hwsim/``), or None for an installed package."""
    root = Path(__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() else None


def _anchors(base: str | Path | None) -> list[tuple[str, str]]:
    """Absolute folders a recorded path is made relative to, first match wins, each with
    the prefix its relative form takes (``..`` for the repository's siblings)."""
    found = [] if base is None else [(os.path.abspath(base), "")]
    root = repo_root()
    if root is not None:
        found.append((str(root), ""))
        if root.parent != root.parent.parent:  # not the file-system root
            found.append((str(root.parent), ".."))
    found.append((os.getcwd(), ""))
    return [(folder, prefix) for folder, prefix in found if folder != os.sep]


def display_path(path: str | Path, base: str | Path | None = None) -> str:
    """How an output records ``path``: never an absolute path of this machine.

    A relative path is returned as given.  An absolute one is made relative to ``base``
    (the run folder) when inside it, else to the repository when inside it (or
    ``../name/...`` for a sibling of the repository, such as ``../shared/data``), else to
    the working folder; a path outside all of them is returned as given.
    """
    text = str(path)
    if not os.path.isabs(text):
        return text
    candidates = dict.fromkeys([os.path.normpath(text), os.path.realpath(text)])
    for folder, prefix in _anchors(base):
        for target in candidates:
            for anchor in dict.fromkeys([folder, os.path.realpath(folder)]):
                if target == anchor or target.startswith(anchor.rstrip(os.sep) + os.sep):
                    rel = Path(os.path.relpath(target, anchor))
                    return (Path(prefix) / rel).as_posix() if prefix else rel.as_posix()
    return text


def display_text(text: str, base: str | Path | None = None) -> str:
    """``text`` (an error message, a note) with every absolute path under the folders of
    :func:`display_path` written as that function writes it."""
    for folder, prefix in _anchors(base):
        pattern = re.compile(r"(?<![\w./~-])" + re.escape(folder.rstrip(os.sep) + os.sep))
        text = pattern.sub(lambda _, short=f"{prefix}/" if prefix else "": short, text)
    return text


def locate(text: str, *bases: str | Path | None) -> Path:
    """The file a recorded path names: ``text`` itself when absolute, else the first of
    ``bases``, the repository and the working folder it exists under (``text`` as given
    when none has it)."""
    path = Path(text)
    if path.is_absolute():
        return path
    root = repo_root()
    for base in (*bases, root, Path.cwd()):
        if base is not None and (Path(base) / path).exists():
            return Path(base) / path
    return path


# ------------------------------------------------------------------ planned, atomic outputs

#: The kinds of output :func:`plan_outputs` checks: a file is written, a folder created.
FILE, FOLDER = "file", "folder"

PathLike = str | os.PathLike


def _stat(path: Path, key: str) -> os.stat_result | None:
    """``os.stat(path)``, None when it does not exist; any other OS error is bad input."""
    try:
        return os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        why = f"cannot use this path: {exc.strerror}"
        raise InputError(why, source=str(path), key=key) from None


def _input_entries(inputs: Iterable[tuple[str, PathLike | None]]) -> list[tuple]:
    """Each existing input as (key, path, real path, (device, inode), is a folder)."""
    found = []
    for key, path in inputs:
        if path is None or not str(path) or str(path).startswith("<"):  # built-in
            continue
        info = _stat(Path(path), key)
        if info is not None:
            is_dir = Path(path).is_dir()
            found.append((key, path, os.path.realpath(path), (info.st_dev, info.st_ino), is_dir))
    return found


def _check_kind(path: Path, key: str, kind: str) -> None:
    """A folder where a file goes, a file where a folder goes (or above either): refused."""
    info = _stat(path, key)
    if info is not None:
        if kind == FILE and Path(path).is_dir():
            raise InputError("is a folder, expected a file name", source=str(path), key=key)
        if kind == FOLDER and not Path(path).is_dir():
            raise InputError("exists and is not a folder", source=str(path), key=key)
        return
    for parent in path.parents:  # the nearest existing folder above it
        if _stat(parent, key) is not None:
            if not parent.is_dir():
                what = "output folder" if kind == FOLDER else "its folder"
                why = f"cannot create {what}: {parent} exists and is not a folder"
                raise InputError(why, source=str(path), key=key)
            return


def _check_not_input(path: Path, key: str, found: list[tuple]) -> None:
    """An output that is one of the command's inputs, or inside an input folder, is refused."""
    real = os.path.realpath(path)
    info = _stat(path, key)
    for in_key, in_path, in_real, in_id, in_dir in found:
        same = real == in_real or (info is not None and (info.st_dev, info.st_ino) == in_id)
        inside = in_dir and real.startswith(in_real.rstrip(os.sep) + os.sep)
        if same or inside:
            what = "is" if same else "is inside"
            raise InputError(
                f"{what} the input {in_path} ({in_key}); an output never replaces an input",
                source=str(path),
                key=key,
            )


def plan_outputs(
    inputs: Iterable[tuple[str, PathLike | None]],
    outputs: Iterable[tuple[str, PathLike | None, str]],
) -> list[Path]:
    """Check every output of a command before any work, then create its folders.

    ``inputs`` are ``(flag, path)`` pairs: every file the command reads (a folder, such
    as a DICOM series or a run folder, stands for every file inside it); ``outputs`` are
    ``(flag, path, FILE | FOLDER)``: every file and folder it will write.  Refused as a
    one-line :class:`InputError` (exit 2), before anything is created: an output that is
    an input (same real path or same file) or lies inside an input folder, a folder where
    a file goes or a file where a folder goes.  Then each folder is created and each
    file's folder checked writable (:func:`output_folder`, :func:`output_file`).
    ``None`` paths are skipped.  Returns the outputs' paths in order.
    """
    found = _input_entries([*inputs, *reads()])
    planned = [(key, Path(path), kind) for key, path, kind in outputs if path is not None]
    for key, path, kind in planned:
        _check_kind(path, key, kind)
        if kind == FILE:
            _check_not_input(path, key, found)
    for key, path, kind in planned:
        if kind == FOLDER:
            output_folder(path, key=key)
        else:
            output_file(path, key=key)
    return [path for _, path, _ in planned]


def in_folder(key: str, folder: PathLike, files: Iterable[PathLike]) -> list[tuple[str, Path, str]]:
    """``folder`` and the ``files`` a command writes in it, as :func:`plan_outputs` takes
    them (every output named by the flag ``key`` that chose the folder)."""
    return [(key, Path(folder), FOLDER), *((key, Path(f), FILE) for f in files)]


@contextmanager
def atomic_write(path: PathLike) -> Iterator[Path]:
    """A temporary name next to ``path`` (same suffix, so writers that read the format
    from it work) that is renamed onto ``path`` when the block ends without an error;
    on an error it is removed and ``path`` keeps its earlier content.

    Every file hwsim writes goes through here, so a failed or interrupted run never
    leaves a half-written file and never destroys an earlier result.  A file the command
    read (:func:`recording_reads`) is refused, and an operating-system error inside the
    block (no space left, which ``write`` reports without a name) names ``path``.
    """
    target = Path(path)
    _check_not_input(target, "output", _input_entries(reads()))
    tmp = target.with_name(f".{target.stem}.partial-{os.getpid()}{target.suffix}")
    try:
        with naming(target, tmp):
            yield tmp
            os.replace(tmp, target)
    finally:
        with suppress(OSError):
            tmp.unlink()


@contextmanager
def naming(path: PathLike, *aliases: PathLike) -> Iterator[None]:
    """An ``OSError`` raised inside the block without a file name (``ENOSPC`` from
    ``write``, ``EIO``, ...) or naming one of ``aliases`` (a temporary name) is raised
    again naming ``path``, so the error boundary's line says which file."""
    try:
        yield
    except OSError as exc:
        hidden = {os.fspath(a) for a in aliases}
        name = exc.filename
        if name is not None and os.fsdecode(name) not in hidden:
            raise
        code = exc.errno
        why = exc.strerror or (os.strerror(code) if code else str(exc) or type(exc).__name__)
        raise OSError(code, why, os.fspath(path)) from exc


def write_text_atomic(path: PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` through :func:`atomic_write`; returns ``path``."""
    with atomic_write(path) as tmp:
        tmp.write_text(text)
    return Path(path)
