"""A small VCD (IEEE 1364 value change dump) writer for cycle-model traces.

Signal names follow the RTL's ports (``i__valid``, ``i__payload``, ``o__valid``,
``o__payload`` as Amaranth names a stream port's members), under nested scopes made from
the component path (``pipeline[0].interp`` becomes ``pipeline_0`` / ``interp``), so a
waveform viewer shows the cycle model and the RTL the same way.  Changes are buffered
and written in time order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hwsim.core.paths import write_text_atomic

__all__ = ["VcdTrace"]

_ID_CHARS = [chr(c) for c in range(33, 127)]


def _ident(n: int) -> str:
    out = ""
    while True:
        out += _ID_CHARS[n % len(_ID_CHARS)]
        n //= len(_ID_CHARS)
        if not n:
            return out


class VcdTrace:
    """Collect value changes, then :meth:`write` a VCD file.

    Parameters
    ----------
    limit : int
        Most value changes kept; a trace that would exceed it raises ``ValueError``
        (traces are for small scenes).
    """

    def __init__(self, limit: int = 5_000_000) -> None:
        self.limit = limit
        self.signals: dict[tuple[str, str], tuple[str, int]] = {}
        self.changes: list[tuple[np.ndarray, str, np.ndarray]] = []
        self.count = 0

    def signal(self, scope: str, name: str, width: int) -> str:
        """Declare (once) a ``width``-bit signal; returns its VCD identifier."""
        key = (scope, name)
        if key not in self.signals:
            self.signals[key] = (_ident(len(self.signals)), int(width))
        return self.signals[key][0]

    def record(self, scope: str, name: str, width: int, cycles, values) -> None:
        """Values of a signal at the given cycles (only changes are kept)."""
        ident = self.signal(scope, name, width)
        cycles = np.asarray(cycles, dtype=np.int64).ravel()
        values = np.asarray(values, dtype=np.int64).ravel()
        if cycles.size == 0:
            return
        order = np.argsort(cycles, kind="stable")
        cycles, values = cycles[order], values[order]
        keep = np.ones(cycles.size, dtype=bool)
        keep[1:] = values[1:] != values[:-1]
        self.count += int(keep.sum())
        if self.count > self.limit:
            raise ValueError(
                f"trace over {self.limit} value changes: trace a smaller scene (--trace)"
            )
        self.changes.append((cycles[keep], ident, values[keep] & ((1 << width) - 1)))

    def write(self, path: str | Path, timescale: str = "1 ns") -> Path:
        """Write the VCD file (one time unit per clock cycle)."""
        path = Path(path)
        lines = ["$timescale " + timescale + " $end"]
        tree: dict = {}
        for (scope, name), (ident, width) in self.signals.items():
            node = tree
            for part in scope.replace("[", "_").replace("]", "").split("."):
                node = node.setdefault(part, {})
            node.setdefault(None, []).append((name, ident, width))

        def emit(node: dict) -> None:
            for name, ident, width in node.get(None, []):
                lines.append(f"$var wire {width} {ident} {name} $end")
            for part, child in node.items():
                if part is not None:
                    lines.append(f"$scope module {part} $end")
                    emit(child)
                    lines.append("$upscope $end")

        emit(tree)
        lines.append("$enddefinitions $end")
        if self.changes:
            times = np.concatenate([c for c, _, _ in self.changes])
            idents = np.concatenate([[i] * c.size for c, i, _ in self.changes])
            values = np.concatenate([v for _, _, v in self.changes])
            widths = {ident: width for ident, width in self.signals.values()}
            order = np.argsort(times, kind="stable")
            last = None
            for k in order.tolist():
                t = int(times[k])
                if t != last:
                    lines.append(f"#{t}")
                    last = t
                ident = str(idents[k])
                w = widths[ident]
                v = int(values[k])
                lines.append(f"{v}{ident}" if w == 1 else f"b{v:b} {ident}")
        write_text_atomic(path, "\n".join(lines) + "\n")  # the earlier trace kept until done
        return path
