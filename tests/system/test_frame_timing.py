"""One frame time, printed and written: the render summary's ms/frame and fps are the
numbers ``stats.json`` holds (``hwsim.run.output.frame_timing``), a supervolume's with and
without the host's read back of its bricks, each labelled (issue 32)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from hwsim.cli.commands import main
from hwsim.run.fidelity import resolve_arch

pytestmark = pytest.mark.system

_RATE = re.compile(r"([\d.]+) ms/frame, ([\d.]+) fps")


def _render(tmp_path: Path, capsys, arch: str, fidelity: str) -> tuple[dict, list[str]]:
    out = tmp_path / "out"
    argv = ["render", "--phantom", "head:size=24", "--image", "24", "--arch", arch]
    assert main([*argv, "--fidelity", fidelity, "--out", str(out)]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "ms/frame" in line]
    return json.loads((out / "stats.json").read_text()), lines


@pytest.mark.parametrize("fidelity", ["transaction", "cycle"])
def test_a_supervolume_prints_the_machine_and_the_host_rate_it_writes(tmp_path, capsys, fidelity):
    arch = tmp_path / "vp500-small.toml"
    text = Path(resolve_arch("volumepro500").source).read_text()
    arch.write_text(text.replace("max_volume = [256, 256, 256]", "max_volume = [16, 16, 16]"))
    stats, lines = _render(tmp_path, capsys, str(arch), fidelity)
    assert stats["derived"]["supervolume"]["bricks"] == 8
    machine = stats["cycles"] / stats["clock_hz"]
    assert stats["machine_frame_seconds"] == pytest.approx(machine)
    assert stats["host_seconds"] == stats["derived"]["supervolume"]["host_seconds"] > 0
    assert stats["frame_seconds"] == pytest.approx(machine + stats["host_seconds"])
    assert stats["frames_per_second"] == pytest.approx(1 / stats["frame_seconds"])
    assert stats["machine_frames_per_second"] == pytest.approx(1 / machine)
    # No second, smaller frame time among the derived figures.
    assert "frame_seconds" not in stats["derived"]
    assert "frames_per_second" not in stats["derived"]
    (machine_line, host_line) = lines
    assert "fps on the machine" in machine_line
    assert "with the host's read back of 8 bricks" in host_line
    for line, key in ((machine_line, "machine_"), (host_line, "")):
        ms, fps = map(float, _RATE.search(line).groups())
        assert ms == pytest.approx(stats[f"{key}frame_seconds"] * 1e3, abs=6e-4)
        assert fps == pytest.approx(stats[f"{key}frames_per_second"], abs=0.06)
    assert float(_RATE.search(host_line)[2]) < float(_RATE.search(machine_line)[2])


def test_a_one_pass_frame_prints_the_one_rate_it_writes(tmp_path, capsys):
    stats, lines = _render(tmp_path, capsys, "volumepro500", "transaction")
    assert stats["host_seconds"] == 0.0
    assert stats["frame_seconds"] == stats["machine_frame_seconds"]
    # The same rate, 1 / (cycles / f) against f / cycles: equal to the last bit or two.
    fps = stats["derived"]["frames_per_second"]
    assert stats["frames_per_second"] == pytest.approx(fps, rel=1e-12)
    (line,) = lines
    ms, fps = map(float, _RATE.search(line).groups())
    assert ms == pytest.approx(stats["frame_seconds"] * 1e3, abs=6e-4)
    assert fps == pytest.approx(stats["frames_per_second"], abs=0.06)
    assert "on the machine" not in line
