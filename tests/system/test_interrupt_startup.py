"""Ctrl-C while the command line starts (issue 33): one line, exit 130, no traceback.

The console script asks ``hwsim.cli`` for ``main`` first; from that moment a SIGINT ends
the process with ``hwsim: interrupted`` (``hwsim.core.interrupt.exit_now``) until the
command installs its own handler.  The signal is sent deterministically by the child
itself at the moment under test (an import hook, or right after the import), so nothing
depends on timing.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hwsim.core.interrupt import EXIT_STATUS, MESSAGE

pytestmark = pytest.mark.system

REPO = Path(__file__).resolve().parents[2]

#: The console script (.venv/bin/hwsim), with SIGINT sent at one moment of its start.
LAUNCHER = """
import os, signal, sys
{hook}
from hwsim.cli import main
{after}
sys.exit(main(["archs"]))
"""
#: Sends SIGINT to this process when ``name`` is first imported (mid-import).
HOOK = """
class Hook:
    def find_spec(self, name, path=None, target=None):
        if name == {name!r}:
            os.kill(os.getpid(), signal.SIGINT)
        return None
sys.meta_path.insert(0, Hook())
"""
CASES = {
    "while importing the commands": (HOOK.format(name="hwsim.cli.progress"), ""),
    "while importing numpy": (HOOK.format(name="numpy"), ""),
    "between the import and the call": ("", "os.kill(os.getpid(), signal.SIGINT)"),
}


@pytest.mark.parametrize("moment", CASES)
def test_sigint_at_start_up_is_one_line(moment):
    hook, after = CASES[moment]
    done = subprocess.run(
        [sys.executable, "-c", LAUNCHER.format(hook=hook, after=after)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == EXIT_STATUS, done.stderr
    assert done.stderr == MESSAGE + "\n", done.stderr
    assert done.stdout == ""  # interrupted before the listing
