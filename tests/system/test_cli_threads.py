"""``hwsim render --threads N``: the frame's threads, never its bits (issue 18)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from cli_errors import one_line_error

from hwsim.cli.commands import main
from hwsim.core.threads import THREADS_ENV_VAR

pytestmark = pytest.mark.system


@pytest.mark.parametrize("fidelity", ["golden", "functional", "cycle"])
def test_threads_change_no_bit_and_are_recorded(tmp_path, fidelity):
    runs = {}
    for threads in ("1", "2"):
        out = tmp_path / threads
        argv = ["render", "--phantom", "head:size=48", "--image", "96", "--arch", "volumepro500"]
        if fidelity == "golden":
            argv = ["render", "--phantom", "head:size=48", "--image", "96"]
        argv += ["--fidelity", fidelity, "--threads", threads, "--out", str(out), "--quiet"]
        before = os.environ.get(THREADS_ENV_VAR)
        assert main(argv) == 0
        assert os.environ.get(THREADS_ENV_VAR) == before  # restored after the command
        stats = json.loads((out / "stats.json").read_text())
        assert stats["host"]["frame_threads"] == int(threads)
        runs[threads] = (np.load(out / "image.npy"), stats["samples"], stats["cycles"])
    one, two = runs["1"], runs["2"]
    assert np.array_equal(one[0], two[0]) and one[1:] == two[1:]


@pytest.mark.parametrize("value", ["0", "257"])
def test_a_bad_thread_count_is_refused(tmp_path, capsys, value):
    argv = ["render", "--phantom", "ball:size=8", "--threads", value, "--out", str(tmp_path)]
    assert main(argv) == 2
    one_line_error(capsys, "--threads", "1 .. 256")
