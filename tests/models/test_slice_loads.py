"""The VolumePro family's compiled slice loads (models/machines/volumepro/slice_loads.py)
give the NumPy form's corner planes, voxel planes, voxel differences and memory counters,
slice by slice, along every principal axis, on both SDRAM layouts and under every fault
that moves data (a stuck module or bank, a dropped ring link, a short beam FIFO)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hwsim.golden import make_plan
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.backend import Backend
from models.frame import frame_of
from models.machines.volumepro import skips_kernel, slice_loads
from models.machines.volumepro.cycle import SlabFaults, SlabMachine
from models.machines.volumepro.timing import mini_blocks_read

pytestmark = pytest.mark.model

CASES = {
    "vp1000": ("volumepro1000", 30, 20, None, {}),
    "vp1000-x": ("volumepro1000", 95, -5, None, {}),
    "vp1000-y": ("volumepro1000", 10, 80, None, {}),
    "vp1000-stuck-bank": ("volumepro1000", -20, 60, SlabFaults(stuck_bank=(1, 2, 3000)), {}),
    "vp1000-dropped-link": ("volumepro1000", 30, 20, SlabFaults(dropped_link=1), {}),
    "vp1000-short-beam-fifo": ("volumepro1000", 30, 20, SlabFaults(beam_fifo_adjust=-1), {}),
    "vp500-stuck-module": ("volumepro500", 30, 20, SlabFaults(stuck_module=(2, 4095)), {}),
    "em-cube": ("em-cube", 100, 10, None, {}),
    "vp500-block-layout": ("volumepro500", 45, 45, None, {"memory": {"skew": "block"}}),
    "vp500-3-modules": ("volumepro500", 30, 20, None, {"memory": {"modules": 3, "banks": 2}}),
    "vp500-P3": ("volumepro500", -60, 30, None, {"pipelines": 3}),
}


def _machines(case):
    arch_name, az, el, faults, changes = case
    arch = resolve_arch(arch_name)
    if "memory" in changes:  # a layout, or module and bank counts not powers of two
        arch = dataclasses.replace(arch, memory={**arch.memory, **changes["memory"]})
    if "pipelines" in changes:
        arch = dataclasses.replace(arch, pipelines=changes["pipelines"])
    volume = make_phantom("head", size=19)  # odd: padding words in the layout
    scene = Scene(
        transfer=TransferSpec(preset="ct"),
        view=ViewSpec(azimuth=az, elevation=el, width=16, height=16),
    )
    tf = resolve_transfer(scene.transfer, volume)
    frame = frame_of(scene, volume, tf, arch, make_plan(scene, volume, arch.order))
    return [SlabMachine(Backend(frame), faults=faults) for _ in range(2)]


@pytest.mark.parametrize("case", list(CASES))
def test_compiled_loads_equal_the_numpy_form(case):
    fast, ref = _machines(CASES[case])
    assert fast.kernel is not None and not fast.be.pre_classified
    for q in range(fast.n_kp):
        planes, voxels = fast.loads.load(q)
        fast._voxels[q] = voxels
        expected = slice_loads.load_numpy(ref, q)
        assert planes.keys() == expected.keys()
        for key, plane in planes.items():
            np.testing.assert_array_equal(plane, expected[key], err_msg=f"{key} of slice {q}")
            if key in ("lo", "hi"):  # LUT entries, kept narrow for the visibility pass
                assert plane.dtype == fast.loads.entry_type
            else:
                assert plane.dtype == expected[key].dtype
        np.testing.assert_array_equal(voxels, ref._voxels[q])
    for q in range(fast.n_kp):
        got, expected = fast._differences(q), slice_loads.differences_numpy(ref, q)
        for key in ("dx", "dy", "dz"):
            np.testing.assert_array_equal(got[key], expected[key], err_msg=f"{key} of slice {q}")
    assert fast.counters.as_dict() == ref.counters.as_dict()
    np.testing.assert_array_equal(fast.memory.reads, ref.memory.reads)
    assert fast.memory.reads.sum() > 0


def test_read_plane_is_the_stream_in_voxel_order():
    """The plane read is the de-skewed stream's voxels at their schedule's slots."""
    fast, ref = _machines(("volumepro500", 30, 20, SlabFaults(stuck_module=(1, 77)), {}))
    for q in (0, 7, fast.n_kp - 1):
        plane = slice_loads.read_plane(fast.memory, fast.kp, q)
        stream = ref.memory.read_slice(ref.kp, q)
        sched = ref.memory.schedule(ref.kp, q)
        valid = sched.valid
        np.testing.assert_array_equal(plane[sched.a[valid], sched.b[valid]], stream[valid])
        assert (plane == 77).any()


@pytest.mark.parametrize("seed", range(4))
def test_compiled_rule6_cells_equal_the_numpy_form(seed):
    """skips_kernel.slice_cells: the beams' clock groups and the mini-blocks read, as
    cycle.py's NumPy form computes them (positions past the edges included)."""
    rng = np.random.default_rng(seed)
    n_a, n_b, P = int(rng.integers(3, 30)), int(rng.integers(3, 30)), int(rng.integers(1, 6))
    C = -(-n_b // P)
    n = int(rng.integers(1, 400))
    pa, pb = rng.uniform(-1.5, n_a + 0.5, n), rng.uniform(-1.5, n_b + 0.5, n)
    live = rng.random(n) < 0.5
    known = live | (rng.random(n) < 0.3)
    cost = np.empty(n_a, dtype=np.int64)
    blocks = np.empty((-(-n_a // 2), -(-n_b // 2)), dtype=bool)
    skips_kernel.slice_cells(
        pa, pb, live, known, P, n_b, np.empty((n_a, C * P), bool), cost, blocks
    )
    ra = np.clip(np.floor(pa), 0, n_a - 1).astype(np.int64)
    rb = np.clip(np.floor(pb), 0, n_b - 1).astype(np.int64)
    cells = np.zeros((n_a, C * P), dtype=bool)
    cells[ra[live], rb[live]] = True
    np.testing.assert_array_equal(cost, cells.reshape(n_a, C, P).any(axis=2).sum(axis=1))
    cells[ra[known], rb[known]] = True
    np.testing.assert_array_equal(blocks, mini_blocks_read(cells[:, :n_b]))
    assert blocks.any()


def test_routes_kept_per_ring_are_the_numpy_forms():
    """The routes kept across frames (``slice_loads._ROUTES``) are keyed by the ring's
    faults: a healthy frame, then one with a dropped link and one with a short beam FIFO
    of the same shape, each still loads the NumPy form's corner planes."""
    slice_loads._ROUTES.clear()
    for faults in (None, SlabFaults(dropped_link=1), SlabFaults(beam_fifo_adjust=-1), None):
        fast, ref = _machines(("volumepro1000", 30, 20, faults, {}))
        for q in range(fast.P + 1):
            planes, _ = fast.loads.load(q)
            np.testing.assert_array_equal(planes["value"], slice_loads.load_numpy(ref, q)["value"])
            assert not fast.loads.routes(q).flags.writeable
    assert len(slice_loads._ROUTES) == 3 * fast.P  # one set per ring, the healthy one reused


def test_specialised_passes_equal_the_generic_ones(monkeypatch):
    """The slab kernel's passes compiled for the machine's own formats (the closure's
    constants) give the generic passes' image, cycles and counters."""
    from models.cycle import render_cycle
    from models.machines.volumepro import slab_kernel

    def frame_of_case(arch_name):
        arch = resolve_arch(arch_name)
        volume = make_phantom("head", size=19)
        scene = Scene(
            transfer=TransferSpec(preset="ct"),
            view=ViewSpec(azimuth=-20, elevation=60, width=16, height=16),
        )
        tf = resolve_transfer(scene.transfer, volume)
        return frame_of(scene, volume, tf, arch, make_plan(scene, volume, arch.order))

    for arch_name in ("volumepro1000", "volumepro500"):
        frame = frame_of_case(arch_name)
        own = render_cycle(frame)
        kernels, asked = slab_kernel._kernels, []

        def generic_kernels(constants=None, kernels=kernels, asked=asked):
            asked.append(constants)
            return kernels(None)

        with monkeypatch.context() as patch:
            patch.setattr(slab_kernel, "_kernels", generic_kernels)
            generic = render_cycle(frame)
        assert asked and asked[0] is not None  # the machine's own formats: specialised
        np.testing.assert_array_equal(own.image, generic.image)
        assert own.cycles == generic.cycles and own.counters == generic.counters
        assert own.counters["simulation.transparent_samples_skipped"] > 0


@pytest.mark.parametrize("seed", range(4))
def test_live_lanes_equal_the_numpy_form(seed):
    """lanes.live_lanes: the live and known samples and the samples per lane of a step,
    as cycle.py's NumPy form computed them (termination on and off, with and without a
    history, skipping on and off); a lane outside the pipelines is refused."""
    from models.machines.volumepro.lanes import live_lanes

    rng = np.random.default_rng(seed)
    n_rays, P = int(rng.integers(5, 300)), int(rng.integers(1, 9))
    rays = np.sort(rng.choice(n_rays, int(rng.integers(1, n_rays)), replace=False))
    alive, history = rng.random(n_rays) < 0.6, rng.random(n_rays) < 0.8
    lanes = rng.integers(0, P, rays.size)
    for ert, past, skipping in [(e, h, s) for e in (0, 1) for h in (0, 1) for s in (0, 1)]:
        live, known = np.empty((2, rays.size), dtype=bool)
        busy = np.full(P, 99, dtype=np.int64)
        hist = history if past else np.zeros(0, dtype=bool)
        assert live_lanes(rays, alive, bool(ert), hist, lanes, bool(skipping), live, known, busy)
        want_live = alive[rays] if ert else np.ones(rays.size, dtype=bool)
        np.testing.assert_array_equal(live, want_live)
        np.testing.assert_array_equal(known, history[rays] if past else True)
        counted = lanes[want_live] if skipping else lanes
        np.testing.assert_array_equal(busy, np.bincount(counted, minlength=P))
    lanes[-1] = P
    assert not live_lanes(rays, alive, True, history, lanes, True, live, known, busy)
