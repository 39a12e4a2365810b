"""VIRIM's event model (``transaction`` rung): boards as SimPy processes, a row at a time.

# Ref: models/machines/virim/config.py; docs/architectures.md ("VIRIM").

Each board's resampler process resamples its image rows one after another (a row's
samples times ``resample_clocks``) into a row store of ``ray_buffers`` rows, streaming:
its ray casters take a row as it starts and spread its samples over ``raycasters``
processors (``ceil(samples x raycast_clocks / raycasters)``, but no less than its longest
ray's), finishing no earlier than one sample after the row's last is resampled.  It shares
with the cycle rung the board assignment (``board_of``), the cost table and the plan's ray
lengths; it does not follow single rays through single processors: the uneven finish of
a board's last rays is estimated (half a mean ray of its last row on every caster but
one), not played.
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np
import simpy

from models.frame import Frame
from models.machines.common.transaction import TxnTiming, report_progress
from models.machines.virim.config import LATENCY, board_of, buffers_of

__all__ = ["VirimTransaction"]


class VirimTransaction:
    """The event model of ``frame`` on VIRIM (``run()`` gives the timing);
    ``pixel_fifo_depth`` is accepted and has no effect (pixels go to the host per ray)."""

    def __init__(self, frame: Frame, *, pixel_fifo_depth: int | None = None) -> None:
        self.frame, self.plan = frame, frame.plan
        self.buffers = buffers_of(frame.arch)
        self.P = frame.arch.pipelines

    def run(self) -> TxnTiming:
        plan, b = self.plan, self.buffers
        samples = plan.j_hi - plan.j_lo + 1
        width = plan.shape[1]
        rows = plan.ray_ids // max(width, 1)
        board = board_of(plan.ray_ids, width, self.P)
        env = simpy.Environment()
        ends = [0] * self.P

        def board_process(
            k: int, loads: np.ndarray, longest_ray: np.ndarray, row_rays: np.ndarray
        ) -> Generator:
            store = simpy.Store(env, capacity=b.ray_buffers)

            def resampler() -> Generator:
                for n, longest, rays in zip(
                    loads.tolist(), longest_ray.tolist(), row_rays.tolist(), strict=True
                ):
                    # A row streams to the casters as it is resampled.
                    yield store.put((n, longest, rays, env.now + n * b.resample_clocks))
                    yield env.timeout(n * b.resample_clocks)

            def casters() -> Generator:
                n = rays = 0
                for _ in range(loads.size):
                    n, longest, rays, resampled = yield store.get()
                    cast = max(-(-n * b.raycast_clocks // b.raycasters), longest * b.raycast_clocks)
                    yield env.timeout(max(cast, resampled + b.raycast_clocks - env.now))
                # The casters finish the last rays unevenly: half a mean ray on all but one.
                ray = n * b.raycast_clocks // max(rays, 1)
                ends[k] = int(env.now) + (b.raycasters - 1) * ray // (2 * b.raycasters)

            env.process(resampler())
            yield env.process(casters())

        for k in range(self.P):
            mine = board == k
            loads = np.bincount(rows[mine], weights=samples[mine]).astype(np.int64)
            longest = np.zeros(loads.size, dtype=np.int64)
            np.maximum.at(longest, rows[mine], samples[mine])
            rays = np.bincount(rows[mine], minlength=loads.size)
            used = loads > 0
            env.process(board_process(k, loads[used], longest[used], rays[used]))
        env.run()
        report_progress(self, 1, 1)
        counters = {
            "board.count": self.P,
            "frame.samples": int(samples.sum()),
            "resampler.busy_cycles": int(samples.sum()) * b.resample_clocks,
            "raycaster.busy_cycles": int(samples.sum()) * b.raycast_clocks,
        }
        return TxnTiming(max(ends) + LATENCY, counters)
