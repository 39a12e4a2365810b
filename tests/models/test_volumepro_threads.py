"""The VolumePro family's cycle rung on two threads (``HWSIM_THREADS=2``): the steps'
geometry ahead of the data pass and the compiled stage's second pass behind it
(models/machines/volumepro/threads.py), and on a slice-FIFO machine the timing pass
beside it (models/machines/volumepro/timing_ahead.py) give the bits of one thread, image, samples,
cycles and every counter, on every machine of the family, with sections, supersampling,
early termination, faults, perspective rays and the unit chain; the helper threads ran
where they should."""

from __future__ import annotations

import dataclasses
import threading
import time
import types

import numpy as np
import pytest

from hwsim.core.threads import using
from hwsim.engine import DeadlockError
from hwsim.golden import make_plan
from hwsim.golden.positions import Step
from hwsim.numerics import SATURATIONS
from hwsim.run.fidelity import resolve_arch
from hwsim.spec.scene import RenderSpec, Scene, TransferSpec, ViewSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom
from models.cycle import render_cycle
from models.frame import frame_of
from models.machines.common.slice_order import SliceOrderMachine
from models.machines.volumepro import threads as vp_threads
from models.machines.volumepro import timing_ahead as vp_timing
from models.machines.volumepro import trilinear as vp_trilinear
from models.machines.volumepro.cycle import SlabFaults, SlabMachine
from models.machines.volumepro.trilinear import TrilinearSource
from models.units.interp import InterpConfig

pytestmark = pytest.mark.model

MODULATED = TransferSpec(preset="ct", gradient_opacity=((100.0, 0.0), (1500.0, 1.0)))


def _scene(az=30, el=20, size=40, projection="parallel", modulated=False, **render):
    view = ViewSpec(
        azimuth=az, elevation=el, width=size, height=size, zoom=1.3, projection=projection
    )
    return Scene(
        transfer=MODULATED if modulated else TransferSpec(preset="ct"),
        view=view,
        render=RenderSpec(mode="composite", **render),
    )


def _case(arch, scene, changes=None, faults=None, compiled=True, behind=True, volume="head"):
    """(machine, changes to it, scene, faults, compiled, second pass behind the data pass,
    phantom)."""
    return arch, changes or {}, scene, faults, compiled, behind, volume


VP500, VP1000 = "volumepro500", "volumepro1000"
SECTIONS = {"section_width": 9}
CASES = {
    "vp500": _case(VP500, _scene()),
    # Visible samples up to the last step: a missing wait before the pixel bus shows.
    "vp500-marschner-lobb": _case(VP500, _scene(az=15), volume="marschner-lobb"),
    "vp500-sections": _case(VP500, _scene(az=-40), SECTIONS),
    "vp500-supersampled": _case(VP500, _scene(20, 50, supersampling=2.0)),
    "vp500-modulated": _case(VP500, _scene(-70, 25, modulated=True)),
    "em-cube": _case("em-cube", _scene(100, 10)),
    "vp1000": _case(VP1000, _scene(-20, 60)),
    # Its kernel ends rays: the second pass stays on the frame's thread.
    "vp1000-early-termination": _case(VP1000, _scene(early_termination=0.9), behind=False),
    # Outside the kernel's scope: the unit chain.
    "vp1000-perspective": _case(VP1000, _scene(-30, 10, projection="perspective"), behind=False),
    "vp500-unit-chain": _case(VP500, _scene(az=60), compiled=False, behind=False),
    "vp500-stuck-module": _case(VP500, _scene(), faults=SlabFaults(stuck_module=(1, 4095))),
    "vp500-dropped-link": _case(VP500, _scene(), faults=SlabFaults(dropped_link=2)),
    # A hand-off that clears accumulators: the second pass stays on the frame's thread.
    "vp500-lost-handoff": _case(
        VP500, _scene(), faults=SlabFaults(dropped_handoff=1), behind=False
    ),
    "vp500-lost-spill": _case(VP500, _scene(az=-40), SECTIONS, SlabFaults(lost_spill=0)),
    # Faults that change the timing pass's inputs (read at the frame's start).
    "vp500-small-buffer": _case(VP500, _scene(), faults=SlabFaults(slab_buffer_adjust=-2000)),
    "vp500-small-pixel-fifo": _case(
        VP500, _scene(az=-40), SECTIONS, SlabFaults(pixel_fifo_depth=2)
    ),
    "em-cube-sections-supersampled": _case("em-cube", _scene(-40, 20, supersampling=1.5), SECTIONS),
}


def _timed_ahead(case) -> bool:
    """Whether a case's timing pass runs beside the data pass: a slice-FIFO machine
    (no skipping) on the compiled stage."""
    return case[0] != VP1000 and case[4]


@pytest.fixture(scope="module")
def volumes():
    return {name: make_phantom(name, size=32) for name in ("head", "marschner-lobb")}


def _render(case, volumes):
    arch_name, changes, scene, faults, compiled, _, phantom = case
    volume = volumes[phantom]
    arch = resolve_arch(arch_name)
    arch = dataclasses.replace(arch, **changes) if changes else arch
    tf = resolve_transfer(scene.transfer, volume)
    frame = frame_of(scene, volume, tf, arch, make_plan(scene, volume, arch.order))
    SATURATIONS.clear()
    run = render_cycle(frame, faults=faults, compiled=compiled)
    return run, dict(SATURATIONS)


@pytest.mark.parametrize("name", list(CASES))
def test_two_threads_give_the_bits_of_one(name, volumes, monkeypatch):
    case = CASES[name]
    launches = {True: 0, False: 0}
    launch = vp_threads.FinishBehind.launch

    def counted(self, fn, args, after):
        launches[self.active] += 1
        if self.active:  # a slow second pass: a missing wait would read unblended rays
            return launch(self, lambda *a: time.sleep(0.002) or fn(*a), args, after)
        return launch(self, fn, args, after)

    monkeypatch.setattr(vp_threads.FinishBehind, "launch", counted)
    played = []  # slices the timing thread had played when the frame joined it
    join = vp_timing.TimingAhead.join
    monkeypatch.setattr(
        vp_timing.TimingAhead, "join", lambda self: played.append(self.played) or join(self)
    )
    ahead = []
    monkeypatch.setattr(
        vp_threads,
        "_ahead",
        lambda items, depth, f=vp_threads._ahead: ahead.append(depth) or f(items, depth),
    )
    with using(1):
        one, sat_one = _render(case, volumes)
    assert launches[True] == 0 and not ahead and not played
    with using(2):
        two, sat_two = _render(case, volumes)
    np.testing.assert_array_equal(two.image, one.image)
    assert (two.samples, two.rays, two.cycles) == (one.samples, one.rays, one.cycles)
    assert two.counters == one.counters
    assert sat_two == sat_one
    assert one.image[..., 3].max() > 0.05  # something was composited
    assert ahead, "the steps were not computed ahead"
    behind = case[5]
    assert (launches[True] > 0) == behind, launches
    # The timing pass ran beside the data pass where it may (slices played before the
    # join), and only there.
    assert (len(played) == 1 and played[0] > 0) == _timed_ahead(case), played
    assert not [t for t in threading.enumerate() if t.name == "hwsim-timing"]


def test_a_frame_that_outgrows_the_guessed_log_room_is_played_again(volumes, monkeypatch):
    """Log room too small for the timing loop beside the data pass: the frame is played
    again at the join, the bits of one thread."""
    guessed = []
    monkeypatch.setattr(vp_timing, "_room", lambda *a: guessed.append(a) or (1, 1))
    case = CASES["vp500-sections"]
    with using(1):
        one, _ = _render(case, volumes)
    with using(2):
        two, _ = _render(case, volumes)
    assert guessed  # the pass ran beside the data pass, on the small room
    np.testing.assert_array_equal(two.image, one.image)
    assert two.cycles == one.cycles and two.counters == one.counters


def test_a_timing_error_is_raised_at_the_frames_end_as_on_one_thread(volumes):
    """An input buffer too small for the sample window: the same error on two threads
    (raised by the timing thread, at the join) as on one."""
    case = dataclasses.replace(SlabFaults(), slab_buffer_adjust=-(10**6))
    arch, changes, scene, _, compiled, behind, phantom = CASES["vp500"]
    broken = (arch, changes, scene, case, compiled, behind, phantom)
    errors = []
    for threads in (1, 2):
        with using(threads), pytest.raises(DeadlockError) as info:
            _render(broken, volumes)
        errors.append(str(info.value))
    assert errors[0] == errors[1] and "input buffer" in errors[0]


def test_an_error_in_the_data_pass_ends_the_timing_thread(volumes, monkeypatch):
    calls = []

    def evict(self, lo, f=SlabMachine._evict):
        calls.append(lo)
        if len(calls) == 5:
            raise ValueError("data pass broke")
        return f(self, lo)

    monkeypatch.setattr(SlabMachine, "_evict", evict)
    with using(2), pytest.raises(ValueError, match="data pass broke"):
        _render(CASES["vp500"], volumes)
    assert not [t for t in threading.enumerate() if t.name == "hwsim-timing"]


def test_an_error_in_the_geometry_thread_is_raised_in_the_frame(volumes, monkeypatch):
    def broken(*args):
        yield from ()
        raise ValueError("geometry broke")

    monkeypatch.setattr(vp_threads, "_geometry", broken)
    with using(2), pytest.raises(ValueError, match="geometry broke"):
        _render(CASES["vp500"], volumes)


def test_passes_behind_run_in_order_and_join_waits_for_them():
    """A worker runs the passes one at a time in launch order; ``join`` returns once all
    ran, their ``after`` calls made on the caller's thread in the same order."""
    gate = threading.Event()
    ran, after = [], []
    behind = vp_threads.FinishBehind(2)
    assert behind.active

    def first(k):
        gate.wait()  # held until the caller has launched the second pass
        ran.append((k, threading.current_thread().name))

    behind.launch(first, (0,), lambda: after.append((0, threading.current_thread().name)))
    behind.launch(ran.append, ((1, "second"),), lambda: after.append((1, "main")))
    assert ran == []  # launch returned while the first pass still waits
    gate.set()
    behind.join()
    assert [k for k, _ in ran] == [0, 1] and ran[0][1].startswith("hwsim-finish")
    assert [k for k, _ in after] == [0, 1]
    assert after[0][1] == threading.current_thread().name
    behind.launch(lambda: 1 / 0, (), lambda: None)
    with pytest.raises(ZeroDivisionError):
        behind.join()
    behind.close()
    assert not behind.active


@pytest.mark.parametrize("hand", [True, False], ids=["hand-offs-ahead", "hand-offs-by-frame"])
@pytest.mark.parametrize("keep", [True, False])
@pytest.mark.parametrize("P", [3, 4])
def test_the_compiled_book_step_marks_what_the_numpy_form_does(keep, hand, P):
    """Slots, lanes, marks, finished rays and, unless a fault makes them on the frame's thread, the
    ring hand-offs (pipelines and moves counted) of the compiled loop and the NumPy
    form (``SliceOrderMachine._hand_off``), step after step."""
    rng = np.random.default_rng(7)
    n, n_a, n_b = 500, 40, 30
    last_j = rng.integers(-1, 6, n)

    def book(compiled):
        machine = types.SimpleNamespace(
            P=P,
            n_a=n_a,
            n_b=n_b,
            be=types.SimpleNamespace(compiled=compiled),
            faults=types.SimpleNamespace(dropped_handoff=None if hand else 0),
        )
        machine._hand_off = types.MethodType(SliceOrderMachine._hand_off, machine)
        machine._slots = types.MethodType(SlabMachine._slots, machine)
        seen = np.zeros((3, n), dtype=np.int64) if keep else None
        return vp_threads.SectionBook(machine, last_j, np.full(n, -1, np.int64), seen, 11)

    numpy_book, compiled_book = book(False), book(True)
    moves, clipped = 0, set()
    for j in range(6):
        rays = np.sort(rng.choice(n, size=rng.integers(0, n), replace=False))
        # Cells from -1 to past the edge, fractions either side of a half: clipped slots.
        ca, cb = rng.integers(-1, n_a + 1, rays.size), rng.integers(-1, n_b + 1, rays.size)
        fa, fb = rng.random((2, rays.size))
        source = types.SimpleNamespace(
            _cells=((ca, None, fa), (cb, None, fb)), q=int(rng.integers(0, 40))
        )
        *want_slots, want, want_tally = numpy_book.step(j, rays, source)
        *got_slots, got, got_tally = compiled_book.step(j, rays, source)
        for g, w in zip(got_slots, want_slots, strict=True):
            np.testing.assert_array_equal(g, w)
        a, b, lanes = want_slots
        np.testing.assert_array_equal(lanes, (source.q + a + b) % P)
        clipped.update(a[(a == 0) | (a == n_a - 1)].tolist())
        np.testing.assert_array_equal(got, want)
        assert got.dtype == want.dtype
        assert (got_tally is None) == (want_tally is None) == (not hand)
        if hand:
            assert list(got_tally) == list(want_tally)
            moves += want_tally[0][1]
    assert numpy_book.done.any() and numpy_book.seen.any()
    assert clipped == {0, n_a - 1}  # slots clipped at both edges
    assert not hand or moves > 0  # rays changed pipelines: the counts compared mean something
    keys = ["seen", "done", "last_seen"] + (["prev_lane"] if hand else [])
    for key in keys:
        np.testing.assert_array_equal(getattr(compiled_book, key), getattr(numpy_book, key))
    assert (compiled_book.prev_lane >= 0).any() == hand


def _numpy_cell(machine, p, like=None):
    """The geometry unit's cells as NumPy computed them before the compiled pass."""
    c = np.floor(p)
    frac = p - c
    quantize = machine.dp.interp.weight.quantize
    if like is None:
        if frac.size and (frac == frac[0]).all():
            weight = np.full(frac.shape, quantize(frac[:1])[0], dtype=np.int64)
            return c.astype(np.int64), weight, frac
        return c.astype(np.int64), quantize(frac), frac
    weight = like[1].copy()
    other = frac != like[2]
    if other.any():
        weight[other] = quantize(frac[other])
    return c.astype(np.int64), weight, frac


@pytest.mark.parametrize("case", ["one-fraction", "many-fractions", "like", "strided", "empty"])
def test_the_compiled_cells_are_the_numpy_cells(case):
    """``SliceOrderMachine.cell`` (a compiled pass on the geometry thread): the cells,
    weights and fractions of NumPy's formula, one fraction per slice or many, the
    weights of ``like`` reused where the fractions agree, on a view and on an empty
    step; a NaN position is still refused."""
    machine = types.SimpleNamespace(dp=types.SimpleNamespace(interp=InterpConfig()))
    rng = np.random.default_rng(3)
    p = np.arange(-3, 60, dtype=np.float64) + 0.375
    like = None
    if case == "many-fractions":
        p = rng.uniform(-3, 60, 500)
    elif case == "like":
        like = _numpy_cell(machine, p)
        p = p + np.where(rng.random(p.size) < 0.3, 0.01, 0.0)  # another weight
    elif case == "strided":
        p = np.stack([p, p * 0.5 + 0.1, p], axis=1)[:, 1]
    elif case == "empty":
        p = p[:0]
    got = SliceOrderMachine.cell(machine, p, like)
    want = _numpy_cell(machine, p, like)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
        assert g.dtype == w.dtype and g.shape == w.shape
    weights = np.unique(got[1]).size
    assert weights == {"one-fraction": 1, "empty": 0}.get(case, weights) and (
        case in ("one-fraction", "empty") or weights > 1
    )
    with pytest.raises(ValueError, match="NaN"):
        SliceOrderMachine.cell(machine, np.array([1.5, np.nan]), like)


def _geometry_machine(rounding="nearest-up", weight_bits=8):
    machine = types.SimpleNamespace(
        dp=types.SimpleNamespace(interp=InterpConfig(rounding=rounding, weight_bits=weight_bits)),
        a_ax=0,
        b_ax=2,
        kp=1,
        n_kp=90,
    )
    machine.cell = types.MethodType(SliceOrderMachine.cell, machine)
    machine.nearest_slice = types.MethodType(SlabMachine.nearest_slice, machine)
    return machine


@pytest.mark.parametrize(
    "case", ["one-fraction", "many-fractions", "half-ways", "strided", "empty", "one-row"]
)
@pytest.mark.parametrize("rounding", ["nearest-up", "nearest-even", "floor", "truncate"])
def test_a_sources_compiled_cells_are_the_geometry_units(case, rounding):
    """``TrilinearSource``'s positions and in-slice cells (one compiled pass on the steps
    thread): those of ``SliceOrderMachine.cell`` on the step's contiguous columns, for
    every rounding, one fraction per slice or many, halfway fractions; a position that
    is not finite or a weight outside its format takes the geometry unit (its error)."""
    machine = _geometry_machine(rounding, weight_bits=3)
    rng = np.random.default_rng(5)
    zyx = np.full((300, 3), 17.25)
    zyx[:, 0] = np.arange(300) * 0.5 - 3.0 + 0.375
    zyx[:, 2] = np.arange(300) * 0.25 + 0.125
    if case == "many-fractions":
        zyx[:, [0, 2]] = rng.uniform(-3, 60, (300, 2))
    elif case == "half-ways":  # exact ties at the weight's resolution (1/16 for 3 bits)
        zyx[:, [0, 2]] = rng.integers(-48, 960, (300, 2)) / 16.0
    elif case == "strided":
        zyx = np.stack([zyx, zyx], axis=1)[:, 0]
    elif case == "empty":
        zyx = zyx[:0]
    elif case == "one-row":
        zyx = zyx[:1]
    got = TrilinearSource(machine, Step(np.arange(zyx.shape[0]), zyx, 1.0))
    columns = [np.ascontiguousarray(zyx[:, ax]) for ax in (0, 2, 1)]
    for g, w in zip((got.pa, got.pb, got.pk), columns, strict=True):
        np.testing.assert_array_equal(g, w)
        assert g.flags.c_contiguous and g.dtype == np.float64
    want = machine.cell(columns[0]), machine.cell(columns[1])
    for got_cell, want_cell in zip(got._cells, want, strict=True):
        for g, w in zip(got_cell, want_cell, strict=True):
            np.testing.assert_array_equal(g, w)
            assert g.dtype == w.dtype and g.shape == w.shape
    if case == "many-fractions":
        assert np.unique(got._cells[0][1]).size > 4  # many weights compared
    assert got.q == machine.nearest_slice(columns[2])
    assert vp_trilinear._compiled_cells(types.SimpleNamespace(m=machine), zyx)
    broken = zyx.copy()
    if broken.size:
        broken[-1, 2] = np.nan
        assert not vp_trilinear._compiled_cells(types.SimpleNamespace(m=machine), broken)
        with pytest.raises(ValueError, match="NaN"):
            TrilinearSource(machine, Step(np.arange(broken.shape[0]), broken, 1.0))


def test_a_weight_outside_its_format_takes_the_geometry_unit(monkeypatch):
    """The compiled cells refuse a weight the format cannot hold (a narrower format than
    the fractions need): the geometry unit then quantises, saturating and counting."""
    machine = _geometry_machine()
    zyx = np.column_stack([np.linspace(0.0, 5.0, 40), np.full(40, 2.0), np.linspace(1, 2, 40)])
    assert vp_trilinear._compiled_cells(types.SimpleNamespace(m=machine), zyx)
    narrow = types.SimpleNamespace(frac_bits=8, rounding="nearest-up", raw_min=0, raw_max=100)
    weight = types.SimpleNamespace(interp=types.SimpleNamespace(weight=narrow))
    assert not vp_trilinear._compiled_cells(
        types.SimpleNamespace(m=types.SimpleNamespace(dp=weight, a_ax=0, b_ax=2, kp=1)), zyx
    )


@pytest.mark.parametrize("sel", ["indices", "negative", "mask", "none", "all", "int32"])
def test_a_subset_source_gathers_what_numpy_indexing_does(sel):
    """``TrilinearSource.subset`` (one compiled gather of its nine arrays for int64
    indices): NumPy's gathers for indices, negative indices, a mask, none, all and other
    index types; an index out of range is NumPy's IndexError."""
    machine = _geometry_machine()
    rng = np.random.default_rng(9)
    zyx = rng.uniform(0, 40, (200, 3))
    source = TrilinearSource(machine, Step(np.arange(200), zyx, 1.0))
    picks = {
        "indices": np.sort(rng.choice(200, 70, replace=False)),
        "negative": -rng.integers(1, 201, 50),
        "mask": rng.random(200) < 0.4,
        "none": np.zeros(0, dtype=np.int64),
        "all": np.arange(200),
        "int32": rng.integers(0, 200, 30).astype(np.int32),
    }[sel]
    got = source.subset(picks)
    for name in ("pa", "pb", "pk"):
        np.testing.assert_array_equal(getattr(got, name), getattr(source, name)[picks])
    for got_cell, cell in zip(got._cells, source._cells, strict=True):
        for g, w in zip(got_cell, cell, strict=True):
            np.testing.assert_array_equal(g, w[picks])
            assert g.dtype == w.dtype
    assert got.q == source.q and got.m is machine
    for bad in (np.array([3, 200]), np.array([-201])):
        with pytest.raises(IndexError):
            source.subset(bad)


def test_the_timing_thread_computes_the_windows(volumes, monkeypatch):
    """On two threads the frame's thread asks one slice window (which fills the taps of
    every step) before the timing thread starts; that thread computes every slice's
    window itself, beside the data pass; one thread asks them all on the frame's."""
    calls = []
    window = SlabMachine.window
    monkeypatch.setattr(
        SlabMachine,
        "window",
        lambda self, j: (
            calls.append(threading.current_thread().name.split("_")[0]) or window(self, j)
        ),
    )
    for threads in (1, 2):
        calls.clear()
        with using(threads):
            run, _ = _render(CASES["vp500"], volumes)
        by = {name: calls.count(name) for name in set(calls)}
        if threads == 1:
            assert set(by) == {"MainThread"}
            n_steps = by["MainThread"]
        else:
            assert by["MainThread"] == 1 and by["hwsim-timing"] == n_steps
            assert by["hwsim-steps"] == n_steps
