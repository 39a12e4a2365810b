"""The VolumePro-family transaction model's chunk reads: each module's burst stream and
the reads handed to the SDRAM ports late and in bulk.

# Ref: docs/transaction.md "The VolumePro 500 / EM-Cube event model" (the memory
#      process); hwsim/memory/sdram_events.py (SdramTransactionPort.read_runs).

:class:`ChunkStreams` holds every chunk's bursts split by module (built by
:meth:`models.machines.volumepro.transaction.SlabTransaction._chunk_streams`);
:class:`DeferredReads` records when each chunk issues and hands the ports every chunk
issued so far when the pipelines first ask when one is ready.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ChunkStreams", "DeferredReads"]


@dataclass
class ChunkStreams:
    """Per module ``(bank, row, bounds, per)``: its bursts of every chunk in read order,
    chunk ``c``'s bursts at ``bounds[c] .. bounds[c + 1] - 1``, ``per[c]`` of them;
    ``batches[c]``: modules chunk ``c`` reads from."""

    modules: list[tuple[np.ndarray, np.ndarray, list[int], np.ndarray]]
    batches: list[int]


class DeferredReads:
    """The chunks' SDRAM reads, handed to the modules' ports only when the pipelines ask
    when a chunk is ready: the controller is causal (a burst's cycles depend on the
    bursts before it and their arrival cycles only), so every chunk issued so far goes in
    one call per module with its own arrival cycle, the same schedule as a call per chunk
    when it issued.  The memory runs about a buffer ahead of the pipelines, so a frame
    makes a few calls per buffer's worth of chunks, not one per chunk and module."""

    def __init__(self, ports, streams: ChunkStreams, nc: int, frames: int) -> None:
        self.ports, self.streams, self.nc = ports, streams, nc
        self.issue_at: list[int] = []  # cycle each chunk issued, in read order
        self.ready: list[int] = []  # cycle each flushed chunk is ready
        for port, (bank, _, _, _) in zip(ports, streams.modules, strict=True):
            port.controller.reserve(frames * bank.size)

    @property
    def issued_count(self) -> int:
        return len(self.issue_at)

    def issued(self, c: int) -> bool:
        return c < len(self.issue_at)

    def issue(self, now: int, g: int, h: int) -> int:
        """Chunks ``g .. h - 1`` issue at cycle ``now``; returns the events the model
        counts for them (one per module batch and one per chunk's readiness)."""
        self.issue_at.extend([now] * (h - g))
        nc = self.nc
        return sum(self.streams.batches[c % nc] for c in range(g, h)) + (h - g)

    def ready_by(self, c: int, now: float) -> bool:
        """Whether chunk ``c`` has issued and its bursts have all arrived by ``now``."""
        return c < len(self.issue_at) and self.ready_at(c) <= now

    def ready_at(self, c: int) -> int:
        """Cycle chunk ``c`` (issued) is ready: its last burst on every module delivered."""
        if c >= len(self.ready):
            self.flush(len(self.issue_at))
        return self.ready[c]

    def flush(self, upto: int) -> None:
        """Hand chunks ``len(self.ready) .. upto - 1`` to the ports (frame by frame)."""
        nc = self.nc
        a = len(self.ready)
        while a < upto:
            f = a // nc
            b = min(upto, (f + 1) * nc)
            c0, c1 = a - f * nc, b - f * nc
            at = self.issue_at[a:b]
            ready = list(at)
            for port, (bank, row, bounds, per) in zip(
                self.ports, self.streams.modules, strict=True
            ):
                lo, hi = bounds[c0], bounds[c1]
                if hi > lo:
                    arrive = np.repeat(np.asarray(at, dtype=np.int64), per[c0:c1])
                    ends = [e - lo for e in bounds[c0 + 1 : c1 + 1]]
                    done = port.read_runs(bank[lo:hi], row[lo:hi], arrive, ends)
                    ready = [max(x, y) for x, y in zip(ready, done, strict=True)]
            self.ready.extend(ready)
            a = b
