"""User mistakes outside the volume files: one exit-2 line naming the key, never exit 1.

Issue 14's corpus of inputs that once ended in "internal error", a silent default, a
runaway render or a modified foreign file.
"""

from __future__ import annotations

import hashlib
import sqlite3

import numpy as np
import pytest
from cli_errors import one_line_error

import hwsim.run.fidelity
from hwsim.cli.commands import main
from hwsim.core import budget

pytestmark = pytest.mark.system

BALL = ["--phantom", "ball:size=8", "--image", "8"]


def _scene(tmp_path, body: str):
    path = tmp_path / "scene.toml"
    path.write_text("schema = 1\n" + body)
    return str(path)


@pytest.fixture
def tables(tmp_path):
    folder = tmp_path / "tables"
    folder.mkdir()
    (folder / "empty.npy").write_bytes(b"")
    np.savez(folder / "two.npz", a=np.zeros((4, 4)))
    np.save(folder / "strings.npy", np.array([["a", "b", "c", "d"]] * 4))
    np.save(folder / "complex.npy", np.zeros((4, 4), dtype=complex))
    np.save(folder / "nan.npy", np.full((4, 4), np.nan))
    np.save(folder / "flat.npy", np.zeros(16))
    np.save(folder / "range.npy", np.full((4, 4), 2.0))
    (folder / "sub").mkdir()
    return folder


@pytest.mark.parametrize(
    ("name", "fragment"),
    [
        ("empty.npy", "not a readable"),
        ("two.npz", ".npz archive"),
        ("strings.npy", "allowed: real numbers"),
        ("complex.npy", "complex128"),
        ("nan.npy", "finite"),
        ("flat.npy", "shape"),
        ("range.npy", "0 .. 1"),
        ("sub", "is a folder"),
    ],
)
def test_transfer_tables(tmp_path, tables, capsys, name, fragment):
    scene = _scene(tmp_path, f'[volume]\nphantom = "ball"\n[transfer]\ntable = "{tables / name}"\n')
    assert main(["render", scene, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "transfer.table", str(tables / name), fragment)


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        ("6.5", "must be an integer, got 6.5"),
        ("true", "must be an integer, got true"),
        ('"6"', "must be an integer, got '6'"),
    ],
)
def test_a_bit_width_that_is_not_an_integer(tmp_path, capsys, value, fragment):
    arch = tmp_path / "arch.toml"
    arch.write_text(
        'schema = 1\nname = "mine"\n[pipeline]\norder = "shear-warp"\ncount = 4\n'
        "clock_hz = 125e6\n[limits]\nvoxel_bits = [8, 12]\nmax_volume = [256, 256, 256]\n"
        f"[formats]\ninterp.weight_bits = {value}\n"
    )
    argv = ["render", "--fidelity", "functional", "--arch", str(arch), *BALL]
    assert main([*argv, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, str(arch), "formats.interp.weight_bits", fragment)


@pytest.mark.parametrize(
    ("flag", "value"),
    [("--view", ""), ("--image", ""), ("--view", "10"), ("--image", "x"), ("--volume", "")],
)
def test_empty_and_malformed_flags_are_refused_not_ignored(tmp_path, capsys, flag, value):
    argv = ["render", "--out", str(tmp_path / "o"), "--quiet", flag, value]
    if flag != "--volume":
        argv += ["--phantom", "ball:size=8"]
    assert main(argv) == 2
    one_line_error(capsys, flag)


def test_raw_keys_on_a_phantom(tmp_path, capsys):
    scene = _scene(tmp_path, '[volume]\nphantom = "ball"\nshape = [8, 8, 8]\n')
    assert main(["render", scene, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "volume.shape", "not a phantom")


def test_deeply_nested_toml(tmp_path, capsys):
    scene = _scene(tmp_path, "x = " + "[" * 50_000 + "]" * 50_000 + "\n")
    assert main(["render", scene, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "nested too deeply")


def test_anisotropic_spacing_is_refused_before_a_runaway_render(tmp_path, capsys):
    scene = _scene(tmp_path, '[volume]\nphantom = "ball"\nspacing = [1e-6, 1, 1]\n')
    assert main(["render", scene, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "spacing", "anisotropic")


def _tripwire(monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("the renderer ran")

    monkeypatch.setattr("hwsim.golden.render_golden", never)


def test_sample_budget_refuses_before_rendering(tmp_path, capsys, monkeypatch):
    _tripwire(monkeypatch)
    monkeypatch.setenv(budget.SAMPLE_ENV_VAR, "100")
    assert main(["render", *BALL, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "render.sample_spacing", "samples", "HWSIM_MAX_SAMPLES")


def test_memory_budget_refuses_a_large_image_before_rendering(tmp_path, capsys, monkeypatch):
    _tripwire(monkeypatch)
    argv = ["render", "--phantom", "ball:size=8", "--image", "2048", "--max-memory", "64M"]
    assert main([*argv, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "2048x2048 frame", "memory budget")
    budget.set_memory_budget(None)


def test_image_side_limit(tmp_path, capsys):
    argv = ["render", "--phantom", "ball:size=8", "--image", "4097"]
    assert main([*argv, "--out", str(tmp_path / "o"), "--quiet"]) == 2
    one_line_error(capsys, "--image", f"1 .. {hwsim.spec.scene.MAX_IMAGE}")


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\narch = ["cube4"]\nfidelity = ["functional"]\nphantom = ["ball"]\n')
    return str(path)


def test_scheduler_without_a_port(tmp_path, capsys, sweep_file):
    argv = ["sweep", sweep_file, "--scheduler", "127.0.0.1", "--db", str(tmp_path / "r.db")]
    assert main([*argv, "--quiet"]) == 2
    one_line_error(capsys, "--scheduler", "no port")


@pytest.fixture
def foreign_db(tmp_path):
    path = tmp_path / "address-book.sqlite"
    conn = sqlite3.connect(path)
    conn.execute("CREATE TABLE people (name TEXT)")
    conn.execute("INSERT INTO people VALUES ('Ada')")
    conn.commit()
    conn.close()
    return path


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("command", ["sweep", "report"])
def test_another_applications_database_is_never_modified(
    tmp_path, capsys, sweep_file, foreign_db, command
):
    before = _digest(foreign_db)
    if command == "sweep":
        argv = ["sweep", sweep_file, "--db", str(foreign_db), "--workers", "1", "--quiet"]
    else:
        argv = ["report", str(foreign_db), "--out", str(tmp_path / "r"), "--quiet"]
    assert main(argv) == 2
    one_line_error(capsys, str(foreign_db), "not an hwsim results database", "people")
    assert _digest(foreign_db) == before
    assert sorted(p.name for p in tmp_path.glob("address-book*")) == ["address-book.sqlite"]


def test_a_text_file_as_database(tmp_path, capsys, sweep_file):
    path = tmp_path / "notes.db"
    path.write_text("not SQLite at all, just some notes\n" * 100)
    assert main(["sweep", sweep_file, "--db", str(path), "--quiet"]) == 2
    one_line_error(capsys, "not an SQLite database")


def test_report_on_a_folder_that_is_not_a_run(tmp_path, capsys):
    (tmp_path / "holiday").mkdir()
    (tmp_path / "holiday" / "photo.txt").write_text("x")
    argv = ["report", str(tmp_path / "holiday"), "--out", str(tmp_path / "r"), "--quiet"]
    assert main(argv) == 2
    one_line_error(capsys, "holiday", "not a run folder")
