"""Hold-out check for issue 33: bad inputs of the issue's classes that no test names.

Each case builds its files in a fresh folder and runs the installed command line in a
child process (``python -m hwsim.cli.commands``, warnings as errors, no ``HWSIM_*``
variables but its own), then asserts what the issue asks of every bad input: exit
status 2, exactly one ``hwsim: error:`` line on stderr, no traceback, and every input
file byte for byte as it was; or, where the input is odd but valid ("either"), a correct
result (exit 0, nothing on stderr) with the inputs untouched.

Classes: a value of the wrong type in each file kind (architecture, scene, technology,
sweep, transfer file, report inputs); operating-system errors on path-taking flags;
inputs named as outputs (directly or inside another file); environment values; formats.

    .venv/bin/python tests/fuzz/holdout_cases.py            # every case, pass rate
    .venv/bin/python tests/fuzz/holdout_cases.py -k nrrd -v # the cases matching 'nrrd'

``tests/fuzz/test_holdout.py`` runs a bounded sample in CI.
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import os
import socket
import subprocess
import sys
import tempfile
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
HWSIM = [sys.executable, "-m", "hwsim.cli.commands"]
RENDER = ["render", "--phantom", "head:size=8", "--image", "8", "--quiet", "--out", "out"]
CYCLE = ["--fidelity", "cycle", "--arch", "cube4"]
SCENE = """schema = 1
[volume]
phantom = "ball"
params = { size = 8 }
[view]
width = 8
height = 8
"""
SWEEP = 'schema = 1\n[sweep]\nphantom = ["ball:size=8"]\nfidelity = ["golden"]\nimage = [8]\n'
LONG = "n" * 300
#: A case still running after this long failed to refuse its input up front.
TIMEOUT = 300


@dataclass
class Setup:
    """What one case runs: argv, extra environment, the files it must leave as they
    were, and whether a correct result is also acceptable ("either")."""

    argv: list[str]
    env: dict[str, str]
    keep: list[Path]
    expect: str = "error"


@dataclass
class Case:
    name: str
    kind: str
    build: Callable[[Path], Setup]


CASES: list[Case] = []


def case(kind: str, expect: str = "error"):
    def register(fn: Callable[[Path], tuple]) -> Callable:
        def build(d: Path) -> Setup:
            argv, keep, *env = fn(d)
            return Setup(argv, env[0] if env else {}, keep, expect)

        CASES.append(Case(fn.__name__, kind, build))
        return fn

    return register


# ------------------------------------------------------------------ file builders


def _arch(d: Path, old: str, new: str, name: str = "a.toml") -> Path:
    text = (REPO / "models/machines/cube4/cube4.toml").read_text()
    assert old in text, old
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.replace(old, new, 1))
    return path


def _tech(d: Path, old: str = "", new: str = "", name: str = "t.toml") -> Path:
    text = (REPO / "hwsim/energy/technologies/cmos45.toml").read_text()
    assert old in text, old
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.replace(old, new, 1) if old else text)
    return path


def _derived(d: Path, base: str, name: str = "d.toml") -> Path:
    text = (REPO / "hwsim/energy/technologies/cmos250.toml").read_text()
    assert 'base = "cmos45"' in text
    path = d / name
    path.write_text(text.replace('base = "cmos45"', f'base = "{base}"'))
    return path


def _scene(d: Path, old: str = "", new: str = "", extra: str = "") -> Path:
    path = d / "s.toml"
    path.write_text((SCENE.replace(old, new, 1) if old else SCENE) + extra)
    return path


def _file(d: Path, name: str, text: str | bytes) -> Path:
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _volume(d: Path, name: str = "v.npy", shape=(8, 8, 8), dtype=np.uint8) -> Path:
    path = d / name
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, (np.arange(np.prod(shape)) % 200).astype(dtype).reshape(shape))
    return path


def _nrrd(d: Path, header: str, data: bytes = bytes(64)) -> Path:
    return _file(d, "v.nrrd", ("NRRD0004\n" + header + "\n\n").encode() + data)


def _run_dir(d: Path, stats: str | None = None, image: np.ndarray | None = None) -> Path:
    run = d / "run"
    run.mkdir(exist_ok=True)
    _file(run, "stats.json", stats if stats is not None else _valid_stats())
    if image is not None:
        np.save(run / "image.npy", image, allow_pickle=False)
    return run


_VALID: dict[str, str] = {}


def _valid_stats() -> str:
    """A real render's stats.json (made once per process)."""
    if "stats" not in _VALID:
        with tempfile.TemporaryDirectory() as tmp:
            done = subprocess.run([*HWSIM, *RENDER], cwd=tmp, capture_output=True, text=True)
            assert done.returncode == 0, done.stderr
            _VALID["stats"] = (Path(tmp) / "out" / "stats.json").read_text()
    return _VALID["stats"]


def _fifo(d: Path, name: str) -> Path:
    path = d / name
    os.mkfifo(path)
    return path


def _loop(d: Path, name: str) -> Path:
    path = d / name
    os.symlink(name, path)  # points at itself
    return path


# ------------------------------------------------------------------ wrong types


@case("arch: wrong type")
def arch_count_string(d):
    a = _arch(d, "count = 4 ", 'count = "four" ')
    return [*RENDER, *CYCLE[:2], "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_clock_array(d):
    a = _arch(d, "clock_hz = 125e6", "clock_hz = [125e6]")
    return [*RENDER, *CYCLE[:2], "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_voxel_bits_string(d):
    a = _arch(d, "voxel_bits = [8, 12, 16]", 'voxel_bits = "8"')
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_modes_string(d):
    a = _arch(d, 'modes = ["composite", "mip"]', 'modes = "composite"')
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_feature_switch_string(d):
    a = _arch(d, "perspective = true", 'perspective = "yes"')
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_negative_max_volume(d):
    a = _arch(d, "max_volume = [1024, 1024, 1024]", "max_volume = [1024, -1, 1024]")
    return [*RENDER, "--fidelity", "functional", "--arch", str(a)], [a]


@case("arch: wrong type")
def arch_name_number(d):
    a = _arch(d, 'name = "cube4"', "name = 4")
    return ["figures", "--arch", str(a), "--out", "fig", "--quiet"], [a]


@case("arch: wrong type")
def arch_technology_array(d):
    a = _arch(d, 'technology = "cmos350"', 'technology = ["cmos350"]')
    return [*RENDER, *CYCLE[:2], "--arch", str(a)], [a]


@case("scene: wrong type")
def scene_width_string(d):
    s = _scene(d, "width = 8", 'width = "8"')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_light_direction_string(d):
    s = _scene(d, extra='[[lights]]\ndirection = "up"\n')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_mode_number(d):
    s = _scene(d, extra="[render]\nmode = 3\n")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_params_string(d):
    s = _scene(d, "params = { size = 8 }", 'params = "size=8"')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_material_inf(d):
    s = _scene(d, extra="[material]\nambient = inf\n")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_crop_string(d):
    s = _scene(d, extra='[crop]\nmin = "a"\n')
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_cut_planes_number(d):
    s = _scene(d, "schema = 1\n", "schema = 1\ncut_planes = 5\n")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("scene: wrong type")
def scene_view_azimuth_array(d):
    s = _scene(d, "width = 8", "width = 8\nazimuth = [1, 2]")
    return ["render", str(s), "--quiet", "--out", "out"], [s]


@case("technology: wrong type")
def tech_node_string(d):
    t = _tech(d, "node_nm = 45", 'node_nm = "45"')
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_vdd_zero(d):
    t = _tech(d, "vdd = 0.9", "vdd = 0")
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_energy_value_string(d):
    t = _tech(d, "value = 0.1,", 'value = "0.1",')
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_base_number(d):
    t = _tech(d, 'name = "cmos45"', 'name = "cmos45"\nbase = 7')
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("technology: wrong type")
def tech_base_missing_file(d):
    t = _derived(d, "nowhere.toml")
    return [*RENDER, *CYCLE, "--technology", str(t)], [t]


@case("sweep: wrong type")
def sweep_phantom_number(d):
    w = _file(d, "w.toml", SWEEP.replace('phantom = ["ball:size=8"]', "phantom = 5"))
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_image_string(d):
    w = _file(d, "w.toml", SWEEP.replace("image = [8]", 'image = ["big"]'))
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_no_sweep_table(d):
    w = _file(d, "w.toml", "schema = 1\n")
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_unknown_fidelity(d):
    w = _file(d, "w.toml", SWEEP.replace('["golden"]', '["warp"]'))
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("sweep: wrong type")
def sweep_zero_pipelines(d):
    w = _file(d, "w.toml", SWEEP + 'arch = ["cube4"]\npipelines = [0]\n')
    return ["sweep", str(w), "--db", "runs.db", "--quiet"], [w]


@case("transfer: wrong type")
def transfer_preset_number(d):
    t = _file(d, "tf.toml", "schema = 1\npreset = 7\n")
    return [*RENDER, "--transfer", str(t)], [t]


@case("transfer: wrong type")
def transfer_table_number(d):
    t = _file(d, "tf.toml", "schema = 1\ntable = 5\n")
    return [*RENDER, "--transfer", str(t)], [t]


@case("report: wrong type")
def report_stats_null(d):
    run = _run_dir(d, "null", np.zeros((8, 8)))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "stats.json"]


@case("report: wrong type")
def report_stats_fidelity_number(d):
    stats = _valid_stats().replace('"fidelity": "golden"', '"fidelity": 5')
    assert '"fidelity": 5' in stats
    run = _run_dir(d, stats, np.zeros((8, 8)))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "stats.json"]


@case("report: wrong type")
def report_image_4d(d):
    run = _run_dir(d, image=np.zeros((2, 2, 2, 2)))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "image.npy"]


@case("report: wrong type")
def report_image_complex(d):
    run = _run_dir(d, image=np.zeros((8, 8), dtype=complex))
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "image.npy"]


@case("report: wrong type")
def report_trade_rows_string(d):
    t = _file(d / "trade", "trade.json", '{"schema": 1, "rows": "x"}')
    return ["report", str(t.parent), "--out", "rep", "--quiet"], [t]


@case("report: wrong type")
def report_figures_list(d):
    f = _file(d / "fig", "figures.json", "[]")
    return ["report", str(f.parent), "--out", "rep", "--quiet"], [f]


# ------------------------------------------------------------------ OS errors


@case("os: path flags")
def transfer_name_too_long(d):
    return [*RENDER, "--transfer", LONG + ".toml"], []


@case("os: path flags")
def technology_fifo(d):
    return [*RENDER, *CYCLE, "--technology", str(_fifo(d, "t.toml"))], []


@case("os: path flags")
def arch_a_folder(d):
    (d / "adir.toml").mkdir()
    return [*RENDER, *CYCLE[:2], "--arch", str(d / "adir.toml")], []


@case("os: path flags")
def report_run_fifo(d):
    return ["report", str(_fifo(d, "run")), "--out", "rep", "--quiet"], []


@case("os: path flags")
def sweep_file_symlink_loop(d):
    return ["sweep", str(_loop(d, "w.toml")), "--db", "runs.db", "--quiet"], []


@case("os: path flags")
def db_under_a_file(d):
    w = _file(d, "w.toml", SWEEP)
    f = _file(d, "f", "x")
    return ["sweep", str(w), "--db", "f/runs.db", "--quiet"], [w, f]


@case("os: path flags")
def trace_under_a_file(d):
    f = _file(d, "f", "x")
    return [*RENDER, *CYCLE, "--trace", "f/t.vcd"], [f]


@case("os: path flags")
def convert_empty_folder(d):
    (d / "empty").mkdir()
    return ["convert", str(d / "empty"), "o.npy"], []


@case("os: path flags")
def volume_a_socket(d):
    path = d / "v.npy"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(path))  # left bound: the file stays a socket
    _SOCKETS.append(sock)
    return ["render", "--volume", str(path), "--image", "8", "--quiet", "--out", "out"], []


_SOCKETS: list[socket.socket] = []


@case("os: path flags")
def trade_out_name_too_long(d):
    return ["trade", "--rungs", "golden", "--out", LONG, "--quiet"], []


@case("os: path flags")
def figures_arch_symlink_loop(d):
    return ["figures", "--arch", str(_loop(d, "a.toml")), "--out", "fig", "--quiet"], []


@case("os: path flags")
def scene_dev_zero(d):
    return ["render", "/dev/zero", "--quiet", "--out", "out"], []


# ------------------------------------------------------------------ inputs as outputs


@case("inputs as outputs")
def trace_is_the_volume(d):
    v = _volume(d)
    return ["render", "--volume", str(v), *CYCLE, "--trace", str(v), "--quiet", "--out", "o"], [v]


@case("inputs as outputs")
def db_is_an_arch_the_sweep_names(d):
    a = _arch(d, 'name = "cube4"', 'name = "mine"')
    w = _file(d, "w.toml", SWEEP.replace('["golden"]', '["functional"]') + 'arch = ["a.toml"]\n')
    return ["sweep", str(w), "--db", str(a), "--quiet"], [a, w]


@case("inputs as outputs")
def out_holds_a_transfer_files_table(d):
    table = d / "out" / "image.npy"
    table.parent.mkdir()
    np.save(table, np.array([[0.0, 0, 0, 0], [255.0, 1, 1, 1]]))
    t = _file(d, "tf.toml", f'schema = 1\ntable = "{table}"\n')
    return [*RENDER, "--transfer", str(t)], [t, table]


@case("inputs as outputs")
def bench_out_holds_the_arch_technology(d):
    t = _tech(d / "out", name="bench.json")
    a = _arch(d, 'technology = "cmos350"', f'technology = "{t}"')
    small = ["--size", "8", "--image", "8", "--repeats", "1", "--rows", "none", "--no-vtk",
             "--no-sweep"]  # fmt: skip
    return ["bench", "--arch", str(a), *small, "--out", "out", "--quiet"], [a, t]


@case("inputs as outputs")
def trace_is_a_base_technology(d):
    b = _tech(d, name="b.toml")
    t = _derived(d, str(b))
    return [*RENDER, *CYCLE, "--technology", str(t), "--trace", str(b)], [b, t]


@case("inputs as outputs")
def report_md_hard_linked_to_stats(d):
    run = _run_dir(d)
    (d / "rep").mkdir()
    os.link(run / "stats.json", d / "rep" / "report.md")
    return ["report", str(run), "--out", "rep", "--quiet"], [run / "stats.json"]


@case("inputs as outputs", expect="either")
def turntable_volume_in_its_out(d):
    v = _volume(d, "out/image.npy")
    return ["render", "--volume", str(v), "--frames", "2", "--image", "8", "--quiet",
            "--out", "out"], [v]  # fmt: skip


@case("inputs as outputs")
def figures_out_is_the_arch_file(d):
    a = _arch(d / "fig", 'name = "cube4"', 'name = "cube4"', name="figures.csv")
    return ["figures", "--arch", str(a), "--out", "fig", "--quiet"], [a]


# ------------------------------------------------------------------ environment


@case("env")
def env_threads_hex(d):
    return RENDER, [], {"HWSIM_THREADS": " 0x10"}


@case("env")
def env_memory_negative(d):
    return RENDER, [], {"HWSIM_MAX_MEMORY": "-5G"}


@case("env")
def env_samples_overflow(d):
    return RENDER, [], {"HWSIM_MAX_SAMPLES": "1e400"}


@case("env")
def env_debug_word(d):
    return RENDER, [], {"HWSIM_DEBUG": "maybe"}


@case("env")
def env_rtl_build_a_file(d):
    f = _file(d, "f", "x")
    return RENDER, [f], {"HWSIM_RTL_BUILD": str(f)}


@case("env")
def env_memory_tiny(d):
    return RENDER, [], {"HWSIM_MAX_MEMORY": "1K"}


@case("env", expect="either")
def env_threads_other_digits(d):
    return RENDER, [], {"HWSIM_THREADS": "\u0661\u0662"}  # Arabic-Indic 12


# ------------------------------------------------------------------ formats


@case("formats")
def nrrd_gzip_of_raw_bytes(d):
    v = _nrrd(d, "type: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: gzip")
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nrrd_sizes_short(d):
    v = _nrrd(d, "type: uint8\ndimension: 3\nsizes: 4 4\nencoding: raw")
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nrrd_middle_endian(d):
    v = _nrrd(d, "type: short\ndimension: 3\nsizes: 4 4 2\nendian: middle\nencoding: raw")
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nrrd_space_directions_garbage(d):
    header = "type: uint8\ndimension: 3\nsizes: 4 4 4\nspace directions: (a,b,c) x y\nencoding: raw"
    v = _nrrd(d, header)
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def npy_two_dimensional(d):
    v = _volume(d, shape=(4, 4))
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats", expect="either")
def npy_bool_volume(d):
    v = _volume(d, dtype=bool)
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nifti_truncated(d):
    import nibabel

    full = d / "full.nii"
    nibabel.save(nibabel.Nifti1Image(np.zeros((4, 4, 4), np.uint8), np.eye(4)), full)
    v = _file(d, "v.nii", full.read_bytes()[:200])
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def unknown_suffix(d):
    v = _file(d, "v.raw", bytes(64))
    return ["render", "--volume", str(v), "--image", "8", "--quiet", "--out", "out"], [v]


@case("formats")
def nii_gz_not_gzip(d):
    v = _file(d, "v.nii.gz", b"\x1f\x8b" + bytes(100))
    return ["convert", str(v), "o.npy"], [v]


@case("formats")
def npy_gzip_named_npy(d):
    v = _file(d, "v.npy", gzip.compress(bytes(100)))
    return ["convert", str(v), "o.nrrd"], [v]


# ------------------------------------------------------------------ running


def _digest(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def run_case(c: Case, root: Path) -> tuple[bool, str]:
    """Run one case in a fresh folder under ``root``: (passed, why not)."""
    d = root / c.name
    d.mkdir()
    setup = c.build(d)
    before = {p: _digest(p) for p in setup.keep}
    environ = {k: v for k, v in os.environ.items() if not k.startswith("HWSIM_")}
    env = {**environ, "PYTHONWARNINGS": "error", **setup.env}
    try:
        done = subprocess.run(
            [*HWSIM, *setup.argv], cwd=d, env=env, capture_output=True, text=True,
            timeout=TIMEOUT,
        )  # fmt: skip
    except subprocess.TimeoutExpired:
        return False, f"still running after {TIMEOUT} s (a bad input that was not refused)"
    err = done.stderr
    changed = [str(p.name) for p in setup.keep if _digest(p) != before[p]]
    if changed:
        return False, f"input changed: {changed}; exit {done.returncode}: {err[-300:]}"
    if "Traceback" in err or "internal error" in err:
        return False, f"exit {done.returncode}: {err.strip()[-400:]}"
    if done.returncode == 0 and setup.expect == "either" and not err.strip():
        return True, "correct result"
    lines = err.strip().splitlines()
    if done.returncode == 2 and len(lines) == 1 and lines[0].startswith("hwsim: error: "):
        return True, lines[0]
    return False, f"exit {done.returncode}: {err.strip()[-400:]}"


def run(cases: list[Case], jobs: int = 4, verbose: bool = False) -> list[tuple[Case, bool, str]]:
    with tempfile.TemporaryDirectory(prefix="hwsim-holdout-") as tmp:
        _valid_stats()  # once, before the threads
        with ThreadPoolExecutor(jobs) as pool:
            results = list(pool.map(lambda c: (c, *run_case(c, Path(tmp))), cases))
    for sock in _SOCKETS:
        sock.close()
    for c, ok, why in results:
        if verbose or not ok:
            print(f"{'PASS' if ok else 'FAIL'} {c.kind:<24} {c.name}: {why}")
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only cases whose name holds this")
    parser.add_argument("-j", type=int, default=4, help="cases at once (4)")
    parser.add_argument("-v", action="store_true", help="print passing cases too")
    args = parser.parse_args(argv)
    cases = [c for c in CASES if args.k in c.name]
    results = run(cases, args.j, args.v)
    passed = sum(ok for _, ok, _ in results)
    print(f"hold-out: {passed}/{len(results)} passed ({100 * passed / max(len(results), 1):.0f}%)")
    return 0 if passed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
