"""Replay the cycle rung's SDRAM command streams through the datasheet checker.

# Ref: docs/memory.md "The SDRAM checker and the command trace".

The VolumePro family's cycle rung writes each memory module's command bus into its VCD
waveform (``hwsim render --fidelity cycle --trace FILE.vcd``: scopes ``memory_K.sdram``).
:func:`check_vcd` reads every module's commands back, puts the power-up sequence before
them and replays each through ``sdram_checker`` on Icarus or Verilator
(:func:`rtl.sdram.sim.replay`)::

    python -m rtl.sdram.replay FRAME.vcd --arch volumepro500 [--simulator icarus]

prints one line per module (violations, activations, bursts, precharges, refreshes) and
every violation line, and exits 1 if any module broke a rule.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hwsim.core.errors import InputError
from hwsim.memory import SdramConfig, parse_memory
from hwsim.memory.sdram_trace import read_vcd_commands, with_powerup
from hwsim.spec.arch import load_arch_file
from rtl.sdram.sim import HERE, Replay, replay

__all__ = ["check_vcd", "device_of", "main"]


def device_of(arch: str) -> SdramConfig:
    """The SDRAM device of the architecture ``arch``: a built-in name (its file
    ``models/machines/<family>/<arch>.toml``) or a TOML file's path.  Only the ``[memory]``
    table is read (no machine model is imported: the RTL's layer)."""
    path = Path(arch)
    if not (arch.endswith(".toml") or "/" in arch):
        found = sorted((HERE.parents[1] / "models" / "machines").glob(f"*/{arch}.toml"))
        if not found:
            raise InputError(
                f"unknown architecture {arch!r}",
                key="--arch",
                allowed="a built-in name or FILE.toml",
            )
        path = found[0]
    config = load_arch_file(path)
    return parse_memory(config.memory, source=config.source).sdram


def check_vcd(path, cfg: SdramConfig, simulator: str = "verilator", **override) -> list[Replay]:
    """Every module's command stream in the VCD at ``path`` replayed (module order).

    Raises
    ------
    hwsim.core.errors.InputError
        When the VCD holds no SDRAM command bus (not a VolumePro-family cycle-rung trace),
        or the device is DDR (``data_rate = 2``, VolumePro 1000: the checker is SDR's).
    """
    if cfg.data_rate != 1:
        raise InputError(
            f"the SDRAM checker models SDR devices; this one is data_rate {cfg.data_rate}",
            key="memory.data_rate",
            allowed="1 (SDR: VolumePro 500, EM-Cube)",
        )
    traces = read_vcd_commands(path)
    if not traces:
        raise InputError(
            "no SDRAM command bus in this waveform",
            source=str(path),
            allowed="a VCD of hwsim render --fidelity cycle --trace on a VolumePro-family arch",
        )
    return [
        replay(with_powerup(cfg, traces[k]), cfg, simulator, **override) for k in sorted(traces)
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rtl.sdram.replay", description=__doc__)
    parser.add_argument("vcd", help="waveform of hwsim render --fidelity cycle --trace")
    parser.add_argument("--arch", default="volumepro500", help="the machine rendered")
    parser.add_argument("--simulator", default="verilator", choices=["verilator", "icarus"])
    args = parser.parse_args(argv)
    try:
        results = check_vcd(args.vcd, device_of(args.arch), args.simulator)
    except (InputError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    bad = 0
    for k, got in enumerate(results):
        c = got.counts
        print(
            f"memory[{k}]: {c['violations']} violations, {c['activates']} activates, "
            f"{c['reads']} bursts, {c['precharges']} precharges, {c['refreshes']} refreshes"
        )
        for line in got.violations:
            print(f"  {line}")
        bad += c["violations"]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
