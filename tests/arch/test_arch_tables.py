"""The tables a machine family owns ([formats], [buffers], its rules across tables) are
refused when the architecture file loads, on every path that loads one, before any work
(issue 33: a bad [buffers] value used to surface at machine build, once per sweep run)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_errors import one_line_error

from hwsim import api
from hwsim.cli.commands import main
from hwsim.core.errors import InputError
from hwsim.run.fidelity import resolve_arch
from hwsim.studies.sweep.spec import load_sweep
from models.machines import families

MACHINES = Path(__file__).resolve().parents[2] / "models" / "machines"

#: (built-in file, the table text appended or replaced, the key path refused, allowed).
CASES = [
    ("cube4/cube4.toml", "[buffers]\nslab_buffer_entries = 5", "buffers.slab_buffer_entries", ""),
    (
        "cube4/cube4.toml",
        "[buffers]\nbeam_fifo_entries = -1",
        "buffers.beam_fifo_entries",
        "0 .. 1e+08",
    ),
    (
        "volumepro/em-cube.toml",
        "[buffers]\nbeam_fifo_entries = 'x'",
        "buffers.beam_fifo_entries",
        "",
    ),
    ("vizard2/vizard2.toml", "cache_sets = [4, 1, 4]", "buffers.cache_sets[1]", ">= 2"),
    ("vizard2/vizard2.toml", "ray_tile = 8", "buffers.ray_tile", ""),
    ("vizard2/vizard2.toml", 'skew = "miniblock"', "memory.skew", "block"),
    ("vizard2/vizard2.toml", "modules = 2", "memory.modules", "1"),
    (
        "vizard2/vizard2.toml",
        'gradient.source = "voxel"\ninterp.weight_bits = 99',
        "formats.interp",
        "",
    ),
    (
        "vizard2/vizard2.toml",
        'gradient.source = "voxel"\ninterp.nope = 1',
        "formats.interp.nope",
        "",
    ),
]


def _bad_file(tmp_path: Path, builtin: str, text: str) -> Path:
    """``builtin`` with ``text``: a line replacing the line of the same key, else tables
    appended at the end."""
    lines = (MACHINES / builtin).read_text().splitlines()
    key = text.split("=")[0].strip()
    at = [i for i, line in enumerate(lines) if line.split("=")[0].strip() == key]
    if text.startswith("[") or not at:
        lines.append(text)
    else:
        lines[at[0]] = text
    path = tmp_path / f"bad-{Path(builtin).stem}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(("builtin", "text", "key", "allowed"), CASES)
def test_a_bad_family_table_is_refused_at_load(tmp_path, builtin, text, key, allowed):
    path = _bad_file(tmp_path, builtin, text)
    with pytest.raises(InputError) as info:
        resolve_arch(str(path))
    message = str(info.value)
    assert message.startswith(f"{path}: {key}:") and allowed in message, message
    with pytest.raises(InputError, match=re.escape(key)):
        api.arch(path)


def test_every_family_declares_its_buffers():
    assert all(family.buffers is not None for family in families())


BAD_BUFFERS = CASES[3]


def test_render_refuses_before_the_frame(tmp_path, capsys):
    path = _bad_file(tmp_path, *BAD_BUFFERS[:2])
    argv = ["render", "--arch", str(path), "--fidelity", "cycle", "--out", str(tmp_path / "o")]
    assert main([*argv, "--quiet"]) == 2
    one_line_error(capsys, str(path), BAD_BUFFERS[2])
    assert not (tmp_path / "o").exists()


def test_a_sweep_refuses_the_file_when_it_loads(tmp_path):
    path = _bad_file(tmp_path, *BAD_BUFFERS[:2])
    sweep = tmp_path / "s.toml"
    sweep.write_text(
        f'schema = 1\n[sweep]\narch = ["{path.name}"]\nfidelity = ["cycle"]\n'
        'phantom = ["ball:size=16"]\nimage = [16]\n'
    )
    with pytest.raises(InputError, match=r"buffers\.cache_sets\[1\]"):
        load_sweep(sweep)
