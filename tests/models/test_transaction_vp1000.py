"""The ``transaction`` rung on VolumePro 1000: beam skipping (early ray termination, space
leaping) in the slab machine's event model.

The model (``models/machines/volumepro/vp1000_transaction.py``) takes each ray's
termination step from the functional rung and each slice's live cells from the plan, and
times the frame at beam-group / mini-block-beam-chunk granularity over the shared SDRAM
transaction port.  These tests hold it to the cycle rung (docs/cycle.md rule 6) within
the 2 % contract, and check that its inputs (beams, bursts, clocks) are the machine's.

Partly shared (``hwsim.studies.trade.independence``): both rungs call the SDRAM controller, the
mini-block layout, ``pipeline_latency``, ``slab_buffers``, ``mini_blocks_read`` and the
leaping helpers; the per-beam clock groups (``beam_skips``, from the plan's positions)
and the chunk-granular schedule are the model's own.  The memory timing, which the 2 %
does not see, is compared on its own (``tests/memory/memory_timing.py``): the SDRAM's
counters equal, and the memory stall at the model's finest granularity.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import rungs
from memory_timing import FINEST_GROUPS, assert_memory_timing_agrees, memory_regime

from hwsim.core.errors import InputError, NotAvailableError
from hwsim.golden import make_plan
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import ViewSpec, VolumeSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom, read_volume
from hwsim.volumes.volume import Volume
from models import cycle as cycle_module
from models.frame import frame_of
from models.functional import NEVER, render_functional
from models.machines.volumepro import chunk_reads, vp1000_transaction
from models.machines.volumepro import cycle as volumepro_module
from models.machines.volumepro.vp1000_transaction import Vp1000Transaction
from models.transaction import render_transaction, timing_only, transaction_timing

pytestmark = pytest.mark.model

#: Counters the event model's inputs must share with the cycle rung exactly: rule 6 is
#: decided per beam and per mini-block, not estimated.  Partly a consistency check: the
#: clock groups are computed apart, the mini-blocks read through the shared
#: ``mini_blocks_read``.
EXACT = ("memory.bursts", "memory.mbb_reads", "pipeline.beams_processed", "pipeline.beam_cycles")


def scene_of(phantom="head", az=30, el=20, *, image=40, ert=1.0, **kw):
    return rungs.scene_of(
        az, el, phantom=phantom, size=image, preset="auto", render={"early_termination": ert}, **kw
    )


def machine(leaping: bool):
    return dataclasses.replace(resolve_arch("volumepro1000"), space_leaping=leaping)


@pytest.fixture(scope="module")
def phantoms():
    return rungs.phantom_set(40, 40, 41)


def assert_memory_timing_is_the_cycle_rungs(exact, approx, scene, volume, arch):
    """The memory comparisons of ``memory_timing``: the SDRAM's counters of the rung as
    rendered, and with the stall, of the event model at its finest granularity."""
    assert_memory_timing_agrees(exact.counters, approx.counters, stall=False)
    arch, tf, plan = rungs.prepared(scene, volume, arch)
    finest = transaction_timing(frame_of(scene, volume, tf, arch, plan), groups=FINEST_GROUPS)
    return assert_memory_timing_agrees(exact.counters, finest.counters)


@rungs.skipping_grid
def test_cycles_within_the_contract_of_the_cycle_rung(phantoms, phantom, projection, ert, leaping):
    volume = phantoms[phantom]
    scene = scene_of(phantom, image=volume.shape[0], ert=ert, projection=projection)
    exact, approx = rungs.within_contract(scene, volume, machine(leaping))
    rungs.assert_counters_equal(exact, approx, EXACT)
    assert np.array_equal(approx.image, exact.image)  # functional = cycle image
    assert memory_regime(exact.counters) == "unthrottled"
    assert_memory_timing_is_the_cycle_rungs(exact, approx, scene, volume, machine(leaping))


@pytest.mark.parametrize("view", [(0, 0), (150, -30), (90, 45)])
def test_other_views_within_the_contract(phantoms, view):
    scene = scene_of("head", *view, image=48, ert=0.95)
    exact, approx = rungs.within_contract(scene, phantoms["head"], machine(True))
    assert_memory_timing_is_the_cycle_rungs(exact, approx, scene, phantoms["head"], machine(True))


#: Magnified perspective (rays denser than voxels: slices stretch to their busiest
#: pipeline): (head size, image, view, zoom, ERT threshold, space leaping, pipelines).
#: Each was 2.1-4.7 % short while the model split a slice's live samples evenly over the
#: lanes instead of counting each sample's lane (docs/transaction.md).
MAGNIFIED = {
    "40^3, image 80": (40, 80, (30, 20), 1.2, 1.0, False, 8),
    "40^3, image 80, ERT and leaping": (40, 80, (30, 20), 1.2, 0.95, True, 8),
    "24^3, image 72, view -35,10, ERT": (24, 72, (-35, 10), 1.2, 0.95, False, 8),
    "32^3, image 64, zoom 2, leaping": (32, 64, (30, 20), 2.0, 1.0, True, 8),
    "32^3, image 64, zoom 2, ERT and leaping": (32, 64, (30, 20), 2.0, 0.95, True, 8),
    "40^3, image 40, zoom 2.5, ERT and leaping": (40, 40, (30, 20), 2.5, 0.95, True, 8),
    "40^3, image 80, 16 pipelines": (40, 80, (30, 20), 1.2, 1.0, False, 16),
}


def magnified(case):
    """(scene, volume, machine) of a ``MAGNIFIED`` case."""
    size, image, view, zoom, ert, leaping, pipelines = MAGNIFIED[case]
    scene = scene_of("head", *view, image=image, ert=ert, projection="perspective")
    scene = scene.replace(view=dataclasses.replace(scene.view, zoom=zoom))
    arch = dataclasses.replace(machine(leaping), pipelines=pipelines)
    return scene, make_phantom("head", size=size), arch


@pytest.mark.parametrize("case", list(MAGNIFIED))
def test_magnified_perspective_within_the_contract(case):
    """An image denser than the volume: a slice's live samples outnumber its beams'
    clocks on some pipeline, and the slice stretches to that pipeline's count (rule 4).
    The model counts each live sample's lane (its nearest voxel's module), so the stretch
    equals the cycle rung's; the memory stall is then compared with no allowance."""
    scene, volume, arch = magnified(case)
    exact, approx = rungs.within_contract(scene, volume, arch)
    rungs.assert_counters_equal(exact, approx, EXACT)
    stretch = exact.counters["pipeline.slice_stretch_cycles"]
    assert stretch > 0 and approx.counters["pipelines.stretch_cycles"] == stretch
    assert np.array_equal(approx.image, exact.image)
    assert_memory_timing_is_the_cycle_rungs(exact, approx, scene, volume, arch)


def test_magnified_slices_load_the_lanes_unevenly():
    """Why an even split of the live samples over the ``P`` lanes is short: on a
    magnified view the busiest lane of some slice holds more than ``ceil(live / P)``,
    and the stretch (beyond the beams' clocks) follows the busiest lane."""
    scene, volume, arch = magnified("40^3, image 80, ERT and leaping")
    arch_, tf, plan = rungs.prepared(scene, volume, arch)
    model = Vp1000Transaction(frame_of(scene, volume, tf, arch_, plan))
    model.run()
    sk, P = model.skips, arch.pipelines
    even = -(-sk.live // P)
    assert (sk.busiest >= even).all() and (sk.busiest > even).any()
    beams = sk.cost.sum(axis=1)
    assert (np.maximum(sk.busiest - beams, 0) > np.maximum(even - beams, 0)).any()


def test_magnified_timing_only_gives_the_image_runs_cycles():
    """The timing-only path (the unlit termination pass) times a magnified frame as the
    image run does: the lane counts depend on the rays' ends, found the same way."""
    scene, volume, arch = magnified("24^3, image 72, view -35,10, ERT")
    tf = resolve_transfer(scene.transfer, volume)
    full = render_transaction(frame_of(scene, volume, tf, arch))
    alone = timing_only(frame_of(scene, volume, tf, arch))
    assert alone.image is None and alone.cycles == full.cycles
    assert alone.counters["pipelines.stretch_cycles"] == full.counters["pipelines.stretch_cycles"]


def test_the_plain_slab_model_counts_the_lanes_of_a_shear_image_plan():
    """The same lane count without beam skipping (``SlabTransaction``, all samples): a
    VolumePro 500 in shear-image order with a magnified parallel view stretches its slices
    as the cycle rung does (an even split was 136 stretch clocks short here, -0.18 %)."""
    arch = dataclasses.replace(resolve_arch("volumepro500"), order="shear-image")
    scene = scene_of("head", image=80).replace(
        view=ViewSpec(azimuth=30, elevation=20, width=80, height=80, zoom=1.5)
    )
    exact, approx = rungs.cycle_and_transaction(scene, make_phantom("head", size=40), arch)
    stretch = exact.counters["pipeline.slice_stretch_cycles"]
    assert stretch > 0 and approx.counters["pipelines.stretch_cycles"] == stretch
    rungs.assert_within_contract(exact.cycles, approx.cycles)


def in_32_bit_containers(volume):
    """``volume``'s values (shifted to start at 0) as the 12-bit field of 32-bit
    containers: two SDRAM words, so two bursts, per voxel (docs/cycle.md)."""
    data = (volume.data.astype(np.int64) - int(volume.data.min())).astype(np.uint32)
    wide = Volume(data=data, name=f"{volume.name}32", spacing=volume.spacing)
    return wide.field(0, 12, "value")


#: Frames where the memory sets the pace: (32-bit voxels, space leaping, modules,
#: supersampling, scene options).
MEMORY_BOUND = {
    "32-bit voxels": (True, False, 4, 1.0, {}),
    "32-bit voxels, ERT and leaping": (True, True, 4, 1.0, {"ert": 0.95}),
    "32-bit voxels, perspective": (True, False, 4, 1.0, {"projection": "perspective"}),
    "2 modules, ERT": (False, False, 2, 1.0, {"ert": 0.95}),
    "32-bit voxels, supersampling 2": (True, False, 4, 2.0, {}),
}


@pytest.mark.parametrize("case", list(MEMORY_BOUND))
def test_memory_timing_equals_the_cycle_rungs_where_the_memory_sets_the_pace(phantoms, case):
    """Two bursts a voxel, half the modules, supersampling: frames where the memory is
    the bottleneck, which the 2 % on frame cycles sees least (memory_timing)."""
    wide, leaping, modules, ss, options = MEMORY_BOUND[case]
    volume = in_32_bit_containers(phantoms["head"]) if wide else phantoms["head"]
    arch = machine(leaping)
    arch = dataclasses.replace(arch, memory={**arch.memory, "modules": modules})
    scene = scene_of(image=40, **options)
    scene = scene.replace(render=dataclasses.replace(scene.render, supersampling=ss))
    exact, approx = rungs.within_contract(scene, volume, arch)
    assert_memory_timing_is_the_cycle_rungs(exact, approx, scene, volume, arch)


def test_termination_and_leaping_save_cycles_beams_and_bursts(phantoms):
    volume = phantoms["head"]
    tf = resolve_transfer(scene_of().transfer, volume)
    runs = {}
    for ert in (1.0, 0.95):
        for leaping in (False, True):
            arch = machine(leaping)
            scene = scene_of(ert=ert)
            plan = make_plan(scene, volume, arch.order)
            runs[ert, leaping] = render_transaction(frame_of(scene, volume, tf, arch, plan))
    brute, ert, leap, both = runs[1.0, False], runs[0.95, False], runs[1.0, True], runs[0.95, True]
    assert brute.cycles > ert.cycles > both.cycles and brute.cycles > leap.cycles > both.cycles
    for fast in (ert, leap):
        c, b = fast.counters, brute.counters
        assert c["pipeline.beam_cycles"] < b["pipeline.beam_cycles"]
        assert c["memory.bursts"] < b["memory.bursts"]
    assert ert.counters["ert.stopped_rays"] > 0 == brute.counters["ert.stopped_rays"]
    assert leap.counters["space_leaping.samples_leaped"] > 0
    assert brute.counters["space_leaping.samples_leaped"] == 0
    assert np.array_equal(leap.image, brute.image)  # leaping never changes a bit
    changed = np.abs(ert.image - brute.image).max()
    # The documented threshold effect: at most 1 - threshold, plus one 8-bit output step.
    assert 0 < changed <= 1 - 0.95 + 1 / 255 + 1e-9


def test_brute_force_skips_only_beams_no_ray_reaches(phantoms):
    """Without ERT threshold or leaping, a zoomed-out view still skips the clock groups
    and mini-blocks beside its rays (rule 6); a view covering the slice reads every
    mini-block."""
    volume = phantoms["head"]
    n = volume.shape[0]
    scene = scene_of(az=0, el=0, image=n).replace(
        view=ViewSpec(azimuth=0, elevation=0, width=n, height=n, zoom=1.0)
    )
    t = transaction_timing(
        frame_of(scene, volume, resolve_transfer(scene.transfer, volume), machine(False))
    )
    assert t.counters["memory.bursts"] == (n // 2) ** 3
    small = scene.replace(view=ViewSpec(azimuth=0, elevation=0, width=16, height=16, zoom=0.5))
    tf = resolve_transfer(small.transfer, volume)
    s = transaction_timing(frame_of(small, volume, tf, machine(False)))
    assert s.counters["pipeline.beams_skipped"] > t.counters["pipeline.beams_skipped"]
    assert s.counters["memory.bursts_skipped"] > t.counters["memory.bursts_skipped"] == 0


@pytest.mark.parametrize("projection", ["parallel", "perspective"])
def test_compiled_skips_equal_the_numpy_reference(phantoms, projection):
    """Rule 6 per slice by the compiled loop (``skips_kernel.plan_step_cells``, its own
    positions) and by the NumPy form it replaced: the same clocks, mini-blocks, live
    samples and busiest lanes, with no ray stopping, with the functional rung's ends and
    with random ends, at the machine's pipelines and at counts that are not a power of
    two (lanes by ``mod``, clock groups not a machine word); a mutated end changes them
    (the comparison can fail)."""
    volume = phantoms["head"]
    scene = scene_of(az=35, el=25, image=48, ert=0.9, projection=projection)
    tf = resolve_transfer(scene.transfer, volume)
    model = Vp1000Transaction(frame_of(scene, volume, tf, machine(True)))
    plan = model.plan
    ends = render_functional(frame_of(scene, volume, tf, machine(True))).stopped
    rng = np.random.default_rng(3)
    fields = ("cost", "needed", "live", "busiest")
    for stopped in (None, ends, rng.integers(-1, plan.n_steps, ends.shape)):
        for P, lag in ((model.P, 4), (model.P, 8), (3, 4), (6, 8)):
            runs = [
                vp1000_transaction.beam_skips(
                    plan, P, stopped, lag, model._window_slabs, compiled=compiled
                )
                for compiled in (True, False)
            ]
            for name in fields:
                np.testing.assert_array_equal(getattr(runs[0], name), getattr(runs[1], name))
    alive = np.full(ends.shape, plan.n_steps)
    early = np.full(ends.shape, 2)
    a, b = (
        vp1000_transaction.beam_skips(plan, model.P, s, 4, model._window_slabs)
        for s in (alive, early)
    )
    assert a.live.sum() > b.live.sum() and a.cost.sum() > b.cost.sum()


@pytest.mark.parametrize("projection", ["parallel", "perspective"])
@pytest.mark.parametrize("supersampling", [1.0, 1.7])
def test_all_windows_at_once_equal_the_slice_by_slice_rule(phantoms, projection, supersampling):
    """``_all_windows`` (every slice's slab window from one array of slice positions)
    gives what ``_window_slabs`` gives slice by slice, in both slice directions."""
    volume = phantoms["head"]
    for az in (35, 215):
        scene = scene_of(az=az, el=25, image=40, ert=0.9, projection=projection)
        render = dataclasses.replace(scene.render, supersampling=supersampling)
        scene = scene.replace(render=render)
        tf = resolve_transfer(scene.transfer, volume)
        one, every = (Vp1000Transaction(frame_of(scene, volume, tf, machine(True))) for _ in "ab")
        n = one.plan.n_steps
        every._all_windows(n)
        assert len(every._windows) == n > 0
        assert [every._windows[j] for j in range(n)] == [one._window_slabs(j) for j in range(n)]


def test_termination_steps_come_from_the_functional_rung(phantoms):
    """The one hook in the functional rung: each ray's last live step, the same whether
    the simulation leaps invisible blocks or walks every sample, and equal to what
    the model computes for itself when not given them."""
    volume, arch = phantoms["head"], machine(False)
    scene = scene_of(ert=0.9)
    plan = make_plan(scene, volume, arch.order)
    tf = resolve_transfer(scene.transfer, volume)
    frame = frame_of(scene, volume, tf, arch, plan)
    fast = render_functional(frame).stopped
    slow = render_functional(frame, leap_blocks=False).stopped
    assert np.array_equal(fast, slow)
    stopped = fast[plan.ray_ids]
    assert (stopped < NEVER).any() and (
        stopped[stopped < NEVER] >= plan.j_lo[stopped < NEVER]
    ).all()
    given = transaction_timing(frame, stopped=fast)
    own = transaction_timing(frame)
    assert given.cycles == own.cycles
    mip = scene.replace(render=dataclasses.replace(scene.render, mode="mip"))
    assert render_functional(frame_of(mip, volume, tf, arch, plan)).stopped is None


def test_the_event_model_never_runs_the_cycle_machine(phantoms, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the transaction rung ran the cycle machine")

    monkeypatch.setattr(volumepro_module.SlabMachine, "run", refuse)
    monkeypatch.setattr(cycle_module, "render_cycle", refuse)
    run = render(
        scene_of(ert=0.95), fidelity="transaction", arch="volumepro1000", volume=phantoms["head"]
    )
    assert run.cycles > 0 and run.counters["transaction.events"] > 0


def test_reused_request_logs_leak_nothing_between_frames(phantoms):
    """The SDRAM request logs a frame hands back (``chunk_reads.return_logs``) are the next
    frame's scratch: two different frames alternated, each with logs the other (larger
    or smaller) left filled, count and time exactly as each does with fresh logs."""
    volume, arch = phantoms["head"], machine(False)

    def frame(az, el, image):
        scene = scene_of(az=az, el=el, image=image, ert=0.9)
        return frame_of(
            scene,
            volume,
            resolve_transfer(scene.transfer, volume),
            arch,
            make_plan(scene, volume, arch.order),
        )

    frames = [frame(30, 20, 40), frame(150, -30, 24)]

    def counters(f, **options):
        timing = transaction_timing(f, **options)
        return timing.cycles, {k: v for k, v in timing.counters.items() if "seconds" not in k}

    chunk_reads._pool.clear()
    fresh = []
    for f in frames:
        fresh.append(counters(f))
        chunk_reads._pool.clear()
    pairs = list(zip(frames, fresh, strict=True))
    for f, expected in (pairs + pairs[::-1]) * 2:
        assert counters(f) == expected
        assert chunk_reads._pool, "a finished frame keeps its logs"
    steady = counters(frames[0], steady_state=True)
    chunk_reads._pool.clear()
    assert counters(frames[0], steady_state=True) == steady


def test_what_the_model_refuses(phantoms):
    volume = phantoms["head"]
    scene = scene_of()
    sectioned = dataclasses.replace(machine(False), section_width=8)
    with pytest.raises(NotAvailableError, match="overheads.section_width"):
        transaction_timing(
            frame_of(scene, volume, resolve_transfer(scene.transfer, volume), sectioned)
        )


@pytest.mark.slow
@rungs.real_volume_grid
def test_real_volumes_within_the_contract(shared_data, name, ert, leaping, projection):
    volume = read_volume(shared_data / name)
    scene = scene_of(image=64, ert=ert, projection=projection)
    exact, approx = rungs.within_contract(scene, volume, machine(leaping))
    rungs.assert_counters_equal(exact, approx, EXACT)
    assert memory_regime(exact.counters) in ("unthrottled", "backlogged")
    assert_memory_timing_is_the_cycle_rungs(exact, approx, scene, volume, machine(leaping))


def test_embedded_geometry_stops_rays_as_termination_does():
    """The depth test of embedded geometry ends rays (a stopping test): the functional
    rung reports those stops too, so the beams behind the geometry are skipped as on the
    machine, with no opacity threshold at all."""
    from hwsim.spec.scene import load_scene

    scene = load_scene("head-vp1000")
    scene = scene.replace(
        volume=VolumeSpec(phantom="head", params=(("size", 32),)),
        view=dataclasses.replace(scene.view, width=32, height=32),
        render=dataclasses.replace(scene.render, early_termination=1.0),
    )
    arch = machine(False)
    exact = render(scene, fidelity="cycle", arch=arch)
    approx = render(scene, fidelity="transaction", arch=arch)
    assert approx.counters["ert.stopped_rays"] > 0
    rungs.assert_within_contract(exact.cycles, approx.cycles)
    rungs.assert_counters_equal(exact, approx, EXACT)
    assert np.array_equal(approx.image, exact.image)


@pytest.mark.parametrize("name", ["volumepro500", "em-cube", "volumepro1000"])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20)])
def test_back_to_back_frames_give_the_cycle_rungs_period(name, az, el):
    """Rule 9 (continuous rendering, the published rates' basis): the second frame's fill
    overlaps the first's last slices, the first's pixels drain during the second."""
    volume = make_phantom("head", size=32)
    scene = scene_of(az=az, el=el, image=32, ert=0.95)
    arch = resolve_arch(name)
    plan = make_plan(scene, volume, arch.order)
    tf = resolve_transfer(scene.transfer, volume)
    exact = cycle_module.render_cycle(frame_of(scene, volume, tf, arch, plan), steady_state=True)
    approx = render_transaction(frame_of(scene, volume, tf, arch, plan), steady_state=True)
    period, reference = (
        approx.counters["frame.period_cycles"],
        exact.counters["frame.period_cycles"],
    )
    assert period < approx.cycles  # the fill and the drain overlap the neighbours
    rungs.assert_within_contract(reference, period)
    single = render_transaction(frame_of(scene, volume, tf, arch, plan))
    assert single.cycles == approx.cycles and "frame.period_cycles" not in single.counters


@pytest.mark.parametrize("name", ["cube4", "vizard2"])
def test_back_to_back_frames_are_refused_where_the_model_times_single_frames(name):
    volume = make_phantom("head", size=16)
    scene = scene_of(image=16)
    arch = resolve_arch(name)
    plan = make_plan(scene, volume, arch.order)
    tf = resolve_transfer(scene.transfer, volume)
    with pytest.raises(InputError, match="steady_state"):
        render_transaction(frame_of(scene, volume, tf, arch, plan), steady_state=True)


@pytest.mark.parametrize("modules", [2, 4, 8])
@pytest.mark.parametrize("skipping", [False, True])
def test_split_streams_keep_each_modules_bursts_in_read_order(modules, skipping):
    """``streams_kernel.split_streams`` (its four-module pass and its general loop) against
    a NumPy reference: each module's stream is the bursts of the mini-blocks read with
    that module, in read order (chunk, mbb, mini-block, word)."""
    from models.machines.volumepro.streams_kernel import split_streams

    rng = np.random.default_rng(modules)
    slabs, n_u, n_mb, wpv = 4, 6, 5, 2
    module, bank = (rng.integers(0, k, (slabs, n_u, n_mb * wpv)) for k in (modules, 4))
    row = rng.integers(0, 100, (slabs, n_u, n_mb * wpv))
    spans = np.array([(s, u, min(u + 3, n_u)) for s in (2, 0, 3) for u in (0, 3)])
    needed = rng.random((slabs, n_u, n_mb)) < 0.5 if skipping else np.zeros((0, 0, 0), bool)
    total = slabs * n_u * n_mb * wpv
    banks, rows = np.full((modules, total), -1), np.full((modules, total), -1)
    per = split_streams(
        module.astype(np.int16), bank.astype(np.int16), row, spans, needed, wpv, banks, rows
    )
    keep = np.ones((slabs, n_u, n_mb), bool) if not skipping else needed
    for k in range(modules):
        want_b, want_r, want_per = [], [], []
        for s, u0, u1 in spans:
            words = np.repeat(keep[s, u0:u1], wpv, axis=1) & (module[s, u0:u1] == k)
            want_b += bank[s, u0:u1][words].tolist()
            want_r += row[s, u0:u1][words].tolist()
            want_per.append(int(words.sum()))
        assert per[k].tolist() == want_per
        assert banks[k, : len(want_b)].tolist() == want_b
        assert rows[k, : len(want_r)].tolist() == want_r


class _ContainerBus:
    """The pixel bus on a :class:`simpy.Container` (its form before issue 36's round 8):
    the reference ``PixelBus``'s hand-written FIFO must time exactly like."""

    def __init__(self, env, depth, row_pixels):
        import simpy

        self.env, self.depth = env, depth
        self.fifo = simpy.Container(env, capacity=max(depth, 1), init=0)
        self.batch = max(1, min(row_pixels, -(-depth // 8)))
        self.pushed = self.sent = self.max_occupancy = self.stall_cycles = self.events = 0
        self.end = 0
        self._work = env.event()
        env.process(self._drain())

    @property
    def level(self):
        return self.fifo.level

    def push(self, count):
        waited, left = self.env.now, count
        while left:
            chunk = min(left, self.batch)
            yield self.fifo.put(chunk)
            self.events += 1
            self.pushed += chunk
            self.max_occupancy = max(self.max_occupancy, self.fifo.level)
            left -= chunk
            if not self._work.triggered:
                self._work.succeed()
        self.stall_cycles += int(self.env.now - waited)

    def _drain(self):
        while True:
            if self.fifo.level == 0:
                self._work = self.env.event()
                yield self._work
                continue
            chunk = min(self.fifo.level, self.batch)
            yield self.env.timeout(chunk)
            yield self.fifo.get(chunk)
            self.events += 2
            self.sent += chunk
            self.end = int(self.env.now)


@pytest.mark.parametrize("seed", range(40))
def test_pixel_bus_times_as_the_simpy_container_did(seed):
    """``PixelBus`` (one producer, one consumer, its FIFO written out) against the
    container form: random pushes, some at the same cycle as the bus frees a batch, into
    deep and shallow FIFOs (pushes that wait), with another process's events interleaved:
    every push's resume cycle and the FIFO's level then, and the bus's counters, equal."""
    import simpy

    from models.machines.common.pixel_bus import PixelBus

    rng = np.random.default_rng(seed)
    depth, row = int(rng.integers(1, 60)), int(rng.integers(1, 20))
    pushes = [(int(rng.integers(0, 6)), int(rng.integers(0, 3 * depth))) for _ in range(80)]

    def play(kind):
        env = simpy.Environment()
        bus, resumed = kind(env, depth, row), []

        def pipelines():
            for gap, count in pushes:
                if gap:
                    yield env.timeout(gap)
                yield from bus.push(count)
                resumed.append((env.now, bus.level))

        def ticker():  # events of another process at the same cycles
            while env.now < 2000:
                yield env.timeout(int(rng_tick.integers(1, 4)))

        rng_tick = np.random.default_rng(seed + 100)
        env.process(ticker())
        env.process(pipelines())
        env.run()
        names = ("pushed", "sent", "max_occupancy", "stall_cycles", "events", "end")
        return resumed, [getattr(bus, n) for n in names]

    assert play(PixelBus) == play(_ContainerBus)
    assert play(PixelBus)[1][3] > 0 or depth > 40  # shallow FIFOs made pushes wait
