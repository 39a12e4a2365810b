"""What the CLI tests share: running the entry point in a child process, and what every
bad-input test checks (one ``hwsim: error:`` line on stderr)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path


def one_line_error(capsys, *fragments: str) -> str:
    """stderr of the run just made, asserted to be one ``hwsim: error:`` line holding
    every fragment (the file, the key, the allowed range)."""
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("hwsim: error: "), err
    for fragment in fragments:
        assert fragment in err, err
    return err


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """Run the installed entry point as a user would, in a child process."""
    env = {**os.environ, "PYTHONWARNINGS": "error"}
    return subprocess.run(
        [sys.executable, "-m", "hwsim.cli.commands", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=600,
    )
