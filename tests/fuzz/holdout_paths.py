"""Hold-out cases (issue 33), two classes of bad input: operating-system errors on the
path-taking flags (names too long, FIFOs, folders, symbolic-link loops, sockets, paths
under a file) and inputs named as outputs, directly or inside another file.  Listed in
:data:`CASES`, in order."""

from __future__ import annotations

import os
import socket

import numpy as np
from holdout_files import (
    _SOCKETS,
    CYCLE,
    LONG,
    RENDER,
    SWEEP,
    Case,
    _arch,
    _derived,
    _fifo,
    _file,
    _loop,
    _run_dir,
    _tech,
    _volume,
    registrar,
)

CASES: list[Case] = []
case = registrar(CASES)


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
