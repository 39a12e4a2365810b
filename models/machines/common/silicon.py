"""What a machine is made of, for the energy and area model: its on-chip buffers and the
memory actions a frame performs (each family declares its own in ``silicon.py``).

# Ref: docs/energy.md; hwsim/energy (the prices).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["Access", "Silicon", "Storage", "counter_sum"]


@dataclass(frozen=True)
class Storage:
    """An on-chip buffer: ``copies`` arrays of ``entries`` words of ``word_bits``."""

    name: str
    entries: int
    word_bits: int
    copies: int = 1

    @property
    def bits(self) -> int:
        """Bits of one copy (one SRAM array: what an access's energy depends on)."""
        return self.entries * self.word_bits


@dataclass(frozen=True)
class Access:
    """``count`` actions of a frame on a memory: ``store`` names a :class:`Storage` or
    ``dram`` (external), ``kind`` is ``read`` / ``write`` (``word_bits`` each), or, for
    DRAM, ``activate`` / ``refresh`` (per command)."""

    store: str
    kind: str
    count: int
    word_bits: int = 0


@dataclass(frozen=True)
class Silicon:
    """A machine's buffers (sized for its largest volume: what the chips held) and how
    many lerps its interpolator does per sample (3 on a voxel slice, 7 trilinear)."""

    storage: tuple[Storage, ...]
    lerps: int


def counter_sum(counters: Mapping[str, int], *names: str) -> int:
    """The first of ``names`` present (a ``[]`` in a name sums every lane), else 0: the
    cycle and transaction rungs name some totals differently."""
    for name in names:
        if "[]" in name:
            head, tail = name.split("[]")
            found = [
                v
                for k, v in counters.items()
                if k.startswith(head + "[")
                and k.endswith("]" + tail)
                and k[len(head) + 1 : len(k) - len(tail) - 1].isdigit()
            ]
            if found:
                return int(sum(found))
        elif name in counters:
            return int(counters[name])
    return 0
