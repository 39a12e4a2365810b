"""Cube-4 skewed memory: every clock, one voxel per module, for every principal axis.

Ref: architectures.md section 1.2 -- any run of P consecutive voxels along any axis hits
P distinct modules; here the whole read schedule of every slice is checked.
"""

from __future__ import annotations

import numpy as np
import pytest

from hwsim.engine import Counters
from models.machines.cube4.memory import Cube4Memory

pytestmark = pytest.mark.model


def _volume(shape, rng):
    return rng.integers(0, 4096, size=shape).astype(np.int64)


@pytest.mark.parametrize("P", [1, 3, 4, 7])
@pytest.mark.parametrize("shape", [(5, 6, 9), (8, 8, 8), (3, 11, 4)])
def test_every_slice_of_every_axis_reads_each_voxel_once_one_per_module_per_clock(P, shape, rng):
    raw = _volume(shape, rng)
    counters = Counters()
    mem = Cube4Memory(raw, P, counters)
    for kp in range(3):
        a_ax, b_ax = (ax for ax in range(3) if ax != kp)
        n_a, n_b = shape[a_ax], shape[b_ax]
        for s in range(shape[kp]):
            stream, sched = mem.read_slice(kp, s)
            assert np.array_equal(mem.account(kp, s), sched.valid.sum(axis=1))
            T = n_a * -(-n_b // P)
            assert stream.shape == (P, T)
            # One voxel per module per clock: pipeline m only ever reads module m ...
            z, y, x = sched.zyx
            assert np.all(((x + y + z) % P)[sched.valid] == np.nonzero(sched.valid)[0])
            # ... and the slice's voxels are each read exactly once, with the right value.
            seen = np.zeros((n_a, n_b), dtype=int)
            np.add.at(seen, (sched.a[sched.valid], sched.b[sched.valid]), 1)
            assert np.all(seen == 1)
            assert np.array_equal(stream[sched.valid], raw[z, y, x][sched.valid])
            assert np.all(stream[~sched.valid] == 0)
    assert counters["memory.conflicts"] == 0
    mem.publish()
    total_reads = sum(counters[f"memory.module[{m}].reads"] for m in range(P))
    assert total_reads == 3 * raw.size
    idle = sum(counters[f"memory.module[{m}].idle_slots"] for m in range(P))
    slots = 0
    for kp in range(3):
        n_a, n_b = (shape[ax] for ax in range(3) if ax != kp)
        slots += shape[kp] * P * n_a * -(-n_b // P)  # every module, every clock of a slice
    assert total_reads + idle == slots


def test_a_memory_without_modules_counts_the_same_reads(rng):
    raw = _volume((5, 6, 9), rng)
    full, counting = Counters(), Counters()
    mem = Cube4Memory(raw, 4, full)
    bare = Cube4Memory(None, 4, counting, shape=raw.shape)
    for kp in range(3):
        for s in range(raw.shape[kp]):
            mem.read_slice(kp, s)
            assert np.array_equal(mem.account(kp, s), bare.account(kp, s))
    mem.publish()
    bare.publish()
    assert full.as_dict() == counting.as_dict()


@pytest.mark.parametrize("kp", [0, 1, 2])
def test_256_beams_are_conflict_free_for_every_skew_residue(kp):
    """Full-size beams of a 256^3 machine (one slice per residue of s mod P)."""
    shape = [4, 4, 4]
    shape[(kp + 1) % 3] = 256
    shape[(kp + 2) % 3] = 256
    shape[kp] = 8
    raw = np.zeros(shape, dtype=np.int64)
    counters = Counters()
    mem = Cube4Memory(raw, 4, counters)
    for s in range(4):
        _, sched = mem.read_slice(kp, s)
        mem.account(kp, s)
        assert sched.valid.all()  # 4 divides 256: no idle slot
        z, y, x = sched.zyx
        assert np.all((x + y + z) % 4 == np.arange(4)[:, None])
    assert counters["memory.conflicts"] == 0


def test_a_stuck_module_returns_its_value_for_every_read(rng):
    raw = _volume((4, 6, 6), rng)
    mem = Cube4Memory(raw, 3, Counters(), stuck_module=(1, 77))
    stream, sched = mem.read_slice(0, 2)
    assert np.all(stream[1][sched.valid[1]] == 77)
    z, y, x = sched.zyx
    assert np.array_equal(stream[0][sched.valid[0]], raw[z[0], y[0], x[0]][sched.valid[0]])


@pytest.mark.parametrize(
    ("shape", "P"), [((5, 6, 9), 4), ((3, 4, 8), 8), ((2, 3, 5), 1), ((4, 4, 7), 3)]
)
def test_the_host_load_places_every_voxel_where_the_skew_unit_says(shape, P, rng):
    from models.units.skew import cube4_address_zyx, cube4_module

    raw = _volume(shape, rng)
    modules = Cube4Memory.load(raw, P)
    z, y, x = np.indices(shape)
    m, a = cube4_module(x, y, z, P), cube4_address_zyx(z, y, x, shape, P)
    assert np.array_equal(modules[m, a], raw)
    assert modules.shape[1] == -(-(shape[0] * shape[1] * -(-shape[2] // P) * P) // P)
