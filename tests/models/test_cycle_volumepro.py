"""The cycle rung on VolumePro 500, EM-Cube and VolumePro 1000: bit-identical, timed by mechanisms.

Design section 3: the cycle image equals the functional one bit for bit on every machine;
here the voxels come out of the modelled SDRAM modules (mini-blocks, bursts), through the
de-skew network, ring links and FIFOs (test_cycle_volumepro_faults.py breaks them).  The
timing tests check each rule of docs/cycle.md "The VolumePro family" by turning its
mechanism on and off: refresh, the input buffer, early ray termination, space leaping,
sections.
"""

from __future__ import annotations

import numpy as np
import pytest
import rungs
from rungs import assert_identical, functional_and_cycle, machine, scene_of

from hwsim.golden import make_plan
from hwsim.run.fidelity import render, resolve_arch
from hwsim.spec.scene import CropSpec, TransferSpec
from hwsim.spec.transfer import resolve_transfer
from hwsim.volumes import make_phantom, read_volume
from hwsim.volumes.volume import Volume
from models.cycle import has_cycle_model, render_cycle
from models.frame import frame_of

pytestmark = pytest.mark.model

ARCHS = ["volumepro500", "em-cube", "volumepro1000"]
VIEWS = [(0, 0), (30, 20), (90, 45), (200, -30), (37, -61)]
MODES = ["composite", "mip", "minip", "xray", "iso"]


@pytest.fixture(scope="module")
def head():
    return make_phantom("head", size=21)  # odd: mini-blocks at the far faces are partial


def test_the_volumepro_family_is_modelled():
    for name in ARCHS:
        assert has_cycle_model(resolve_arch(name))


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize("mode", MODES)
def test_bit_identical_over_modes_and_views_parallel(head, arch, mode):
    for az, el in VIEWS:
        fixed, cycle, _ = functional_and_cycle(scene_of(az, el, mode=mode), head, arch)
        assert_identical(fixed, cycle)
        assert cycle.counters["memory.conflicts"] == 0
    if mode == "composite":
        assert cycle.image[..., 3].max() > 0.5  # not a trivially empty picture


@pytest.mark.parametrize("mode", ["composite", "mip", "xray", "iso"])
@pytest.mark.parametrize(("az", "el"), [(0, 0), (30, 20), (150, -30)])
def test_volumepro1000_perspective_is_bit_identical(head, mode, az, el):
    scene = scene_of(az, el, mode=mode, projection="perspective")
    assert_identical(*functional_and_cycle(scene, head, "volumepro1000")[:2])


@pytest.mark.parametrize("pipelines", [1, 3, 8])
def test_any_pipeline_count_against_four_sdram_modules(head, pipelines):
    """The de-skew network feeds P pipelines from M = 4 modules for any P."""
    for arch in ("volumepro500", "volumepro1000"):
        scene = scene_of(60, 25, render={"supersampling": 2.0})
        fixed, cycle, _ = functional_and_cycle(scene, head, machine(arch, pipelines=pipelines))
        assert_identical(fixed, cycle)
        assert cycle.counters["memory.conflicts"] == 0


@pytest.mark.parametrize(
    ("arch", "factor"),
    [
        ("volumepro500", 2.0),
        ("volumepro500", 3.5),
        ("volumepro500", 8.0),
        ("volumepro1000", 0.5),
        ("volumepro1000", 2.5),
    ],
)
def test_z_supersampling_interpolates_across_two_slices_bit_identically(head, arch, factor):
    """Sample slices between voxel slices: trilinear with models.units.interp's lerps."""
    for az, el in [(30, 20), (90, 45), (200, -30)]:
        scene = scene_of(az, el, render={"supersampling": factor})
        fixed, cycle, plan = functional_and_cycle(scene, head, arch)
        assert_identical(fixed, cycle)
    assert plan.n_steps == int(np.floor((21 - 1) * factor + 1e-9)) + 1


def test_supersampling_costs_pipeline_time_in_proportion(head):
    one = functional_and_cycle(scene_of(0, 0), head, "volumepro500")[1]
    four = functional_and_cycle(
        scene_of(0, 0, render={"supersampling": 4.0}), head, "volumepro500"
    )[1]
    # 81 sample slices against 21, each of n_a C clocks, after the priming period that
    # reads voxel slice 0 (rule 3'); memory reads each voxel once.
    assert four.counters["pipeline.beams_processed"] == (81 + 1) * 21
    assert one.counters["pipeline.beams_processed"] == (21 + 1) * 21
    assert one.counters["memory.bursts"] == four.counters["memory.bursts"]
    assert 3.0 < four.cycles / one.cycles < 4.0


#: :data:`rungs.FEATURE_VARIANTS` with the slab machines' crop modes and supersampling.
FEATURE_VARIANTS = {
    "pre-classified": rungs.FEATURE_VARIANTS["pre-classified"],
    "crop-slabs": rungs.FEATURE_VARIANTS["crop"],
    "crop-inverted": {"crop": CropSpec(x=(3.0, 15.0), y=(2.0, 18.0), z=(4.0, 12.5), invert=True)},
    "crop-cross": {"crop": CropSpec(x=(3.0, 15.0), y=(2.0, 18.0), z=(4.0, 12.5), mode="cross")},
    "crop-inverted-fence": {
        "crop": CropSpec(x=(3.0, 9.0), y=(2.0, 8.0), z=(4.0, 6.5), mode="fence", invert=True)
    },
    "thick-cut-plane": rungs.FEATURE_VARIANTS["cut-plane"],
    "gm-modulation": rungs.FEATURE_VARIANTS["gm-modulation"],
    "unlit": rungs.FEATURE_VARIANTS["unlit"],
    "ert": rungs.FEATURE_VARIANTS["ert"],
    "supersampled-ert": {"render": {"supersampling": 2.0, "early_termination": 0.8}},
}


@pytest.mark.parametrize("extra", list(FEATURE_VARIANTS.values()), ids=list(FEATURE_VARIANTS))
@pytest.mark.parametrize("arch", ["volumepro500", "volumepro1000"])
def test_volumepro_features_stay_bit_identical(head, arch, extra):
    assert_identical(*functional_and_cycle(scene_of(40, 15, **extra), head, arch)[:2])


@pytest.mark.parametrize("bits", [8, 12])
def test_eight_and_twelve_bit_voxels(rng, bits):
    data = (rng.random((12, 14, 16)) * ((1 << bits) - 1)).astype(np.uint16)
    data[3:9, 4:10, 5:12] = (1 << bits) - 200
    vol = Volume(data=data, spacing=(1.5, 1.0, 0.8), bits=bits, name="box")
    for az, el in [(20, 10), (100, 0), (0, 80)]:
        scene = scene_of(az, el, transfer=TransferSpec(preset="auto"))
        fixed, cycle, _ = functional_and_cycle(scene, vol, "volumepro500")
        assert_identical(fixed, cycle)
    assert cycle.counters["memory.conflicts"] == 0


def test_volumepro1000_gradients_are_taken_at_voxels(head):
    arch = resolve_arch("volumepro1000")
    assert arch.formats["gradient"]["source"] == "voxel"
    lit = scene_of(30, 20, render={"lighting": True})
    voxel = functional_and_cycle(lit, head, arch)
    sample = functional_and_cycle(lit, head, machine("volumepro1000", formats={}))
    assert_identical(*voxel[:2])
    assert_identical(*sample[:2])
    assert not np.array_equal(voxel[1].image, sample[1].image)  # the source matters


def test_counters_add_up_and_every_mini_block_is_read_once(head):
    fixed, cycle, plan = functional_and_cycle(scene_of(33, 21), head, "volumepro500")
    c = cycle.counters
    units = [u for u in cycle.elaborated_units if u not in ("memory", "ring", "pixel_bus")]
    rungs.assert_slice_counters_add_up(cycle, plan, 4, units)
    # 11 x 11 x 11 mini-blocks of the 21^3 volume (the last ones half used), one burst each.
    assert c["memory.bursts"] == 11**3 == c["memory.mbb_reads"] * 11
    assert (
        c["memory.sdram.row_hits"] + c["memory.sdram.row_misses"] + c["memory.sdram.row_conflicts"]
        == c["memory.bursts"]
    )
    words = sum(c[f"memory.module[{m}].words_read"] for m in range(4))
    assert words == head.data.size  # each voxel delivered once to the de-skew network


@pytest.mark.parametrize("axis_view", [(0, 0), (90, 0), (0, 90)], ids=["z", "x", "y"])
def test_skew_is_conflict_free_along_every_principal_axis(head, axis_view):
    for arch in ARCHS:
        cycle = functional_and_cycle(scene_of(*axis_view, mode="mip"), head, arch)[1]
        assert cycle.counters["memory.conflicts"] == 0


def test_block_layout_without_the_bank_skew_renders_the_same_and_stalls_more(head):
    """``skew = "block"``: mini-blocks skewed across modules only (EM-Cube's block
    skewing without VolumePro's second, bank level): the same image, but consecutive
    bursts of a module now often hit one bank, and the row conflicts that the bank skew
    hides behind other banks' bursts stall the pipelines."""
    memory = dict(resolve_arch("em-cube").memory)
    one_level_arch = machine("em-cube", memory={**memory, "skew": "block"})
    for view in [(90, 0), (0, 90)]:
        scene = scene_of(*view, mode="mip")
        two_level = functional_and_cycle(scene, head, "em-cube")[1]
        fixed, one_level, _ = functional_and_cycle(scene, head, one_level_arch)
        assert_identical(fixed, one_level)
        assert np.array_equal(one_level.image, two_level.image)
        assert one_level.counters["memory.conflicts"] == 0
        stall = "memory.stall_cycles"
        assert one_level.counters[stall] > two_level.counters[stall]
        assert one_level.cycles > two_level.cycles


def test_refresh_and_slower_memory_cost_cycles_by_mechanism(head):
    """Rules 1-3: the pipelines stall exactly when data is late."""
    scene = scene_of(0, 0, mode="mip")
    base = functional_and_cycle(scene, head, "volumepro500")[1]
    memory = dict(resolve_arch("volumepro500").memory)
    no_refresh = functional_and_cycle(
        scene, head, machine("volumepro500", memory={**memory, "t_refi": 0})
    )[1]
    often = functional_and_cycle(
        scene, head, machine("volumepro500", memory={**memory, "t_refi": 40})
    )[1]
    half = functional_and_cycle(
        scene, head, machine("volumepro500", memory={**memory, "clock_ratio": 0.5})
    )[1]
    assert no_refresh.counters["memory.sdram.refreshes"] == 0
    assert 0 < base.counters["memory.sdram.refreshes"] < often.counters["memory.sdram.refreshes"]
    # A refresh every 976 clocks hides in the buffer's slack here; one every 40 does not.
    assert no_refresh.cycles <= base.cycles < often.cycles
    assert often.counters["memory.stall_cycles"] > base.counters["memory.stall_cycles"]
    assert np.array_equal(often.image, base.image)
    # Memory at half the pipeline clock delivers half the voxels per clock: memory-bound.
    T = 21 * -(-21 // 4)
    assert half.cycles > 1.8 * 21 * T and half.counters["memory.stall_cycles"] > 21 * T * 0.8


@pytest.mark.parametrize("factor", [1.0, 2.0])
def test_with_memory_never_late_the_rules_have_their_closed_form(head, factor):
    """Rules 3', 8', 9 with a memory 64x faster than the pipelines and no refresh: the
    continuous period is exactly the beam clocks (the priming period and the sample
    slices, each n_a x C); one frame adds the first burst's arrival and, after the last
    period's first slot, the stream latency and one clock per pixel (every ray finishes
    on the last slice and they come faster than the bus pops them)."""
    memory = dict(resolve_arch("volumepro500").memory)
    fast = machine("volumepro500", memory={**memory, "t_refi": 0, "clock_ratio": 64.0})
    scene = scene_of(0, 0, mode="mip", render={"supersampling": factor})
    tf = resolve_transfer(scene.transfer, head)
    plan = make_plan(scene, head, fast.order)
    result = render_cycle(frame_of(scene, head, tf, fast, plan), steady_state=True)
    c, C = result.counters, -(-21 // 4)
    beams = (plan.n_steps + 1) * 21 * C
    assert c["frame.period_cycles"] == beams == c["pipeline.beam_cycles"]
    first = c["memory.stall_cycles"]
    assert 0 < first <= 16  # the first mini-block beam's bursts: ACT, CAS, 8 beats / 64
    last_period = beams - 21 * C
    pixels = plan.ray_ids.size
    assert result.cycles == last_period + c["pipeline.latency_cycles"] + pixels + first
    assert c["pixel_bus.drain_cycles"] == c["pipeline.latency_cycles"] + pixels - 21 * C


def test_a_pipeline_slice_overhead_adds_per_slice(head):
    scene = scene_of(0, 0, mode="mip")
    base = functional_and_cycle(scene, head, "volumepro500")[1]
    slow = functional_and_cycle(scene, head, machine("volumepro500", slice_overhead_cycles=10))[1]
    assert base.cycles < slow.cycles <= base.cycles + 21 * 10


def test_elision_changes_neither_image_nor_cycles(head):
    for mode in ("mip", "composite"):
        scene = scene_of(30, 20, mode=mode, render={"lighting": mode == "composite"})
        _, lean, _ = functional_and_cycle(scene, head, "volumepro500")
        _, full, _ = functional_and_cycle(scene, head, "volumepro500", elaborate_all=True)
        assert np.array_equal(lean.image, full.image) and lean.cycles == full.cycles
        assert len(full.elaborated_units) >= len(lean.elaborated_units)


def test_early_ray_termination_saves_cycles_on_volumepro1000_only(head):
    """Rule 6: clock groups of a beam holding only terminated rays are not processed, nor
    the mini-blocks only they need read, on VolumePro 1000; the image differs from the
    unterminated one only by the threshold effect (a ray stops once its opacity reaches
    the threshold)."""
    dense = TransferSpec(points=((0.0, 1, 1, 1, 0.0), (200.0, 1, 1, 1, 0.9), (4095.0, 1, 1, 1, 1)))
    scene = scene_of(30, 20, transfer=dense, render={"early_termination": 0.95})
    plain = scene_of(30, 20, transfer=dense, render={"early_termination": 1.0})
    fixed, ert, _ = functional_and_cycle(scene, head, "volumepro1000")
    assert_identical(fixed, ert)
    full = functional_and_cycle(plain, head, "volumepro1000")[1]
    assert ert.cycles < full.cycles
    assert ert.counters["pipeline.beam_cycles"] < full.counters["pipeline.beam_cycles"]
    assert ert.counters["memory.bursts_skipped"] > full.counters["memory.bursts_skipped"]
    alpha = full.image[..., 3]
    differs = np.any(ert.image != full.image, axis=-1)
    assert differs.any() and (alpha[differs] >= 0.95 - 1e-3).all()
    assert np.abs(ert.image - full.image).max() <= 0.05 + 1e-3
    # VolumePro 500 has no ERT hardware: the threshold is honoured, no cycle is saved.
    vp500 = (
        functional_and_cycle(scene, head, "volumepro500")[1],
        functional_and_cycle(plain, head, "volumepro500")[1],
    )
    assert vp500[0].cycles == vp500[1].cycles
    assert vp500[0].counters["pipeline.beams_skipped"] == 0


def test_space_leaping_is_a_feature_users_turn_on(head):
    """Rule 6 with [features] space_leaping = true: empty beams are neither read nor
    processed; the image is bit-identical (skipped samples are provably transparent)."""
    sparse = TransferSpec(
        points=((0.0, 1, 1, 1, 0.0), (2500.0, 1, 1, 1, 0.0), (4095.0, 1, 1, 1, 0.8))
    )
    scene = scene_of(30, 20, transfer=sparse)
    assert resolve_arch("volumepro1000").space_leaping is False
    off = functional_and_cycle(scene, head, "volumepro1000")
    on = functional_and_cycle(scene, head, machine("volumepro1000", space_leaping=True))
    assert_identical(*off[:2])
    assert np.array_equal(on[1].image, off[0].image)
    assert on[1].samples < off[1].samples
    assert on[1].cycles < off[1].cycles
    assert on[1].counters["memory.mbb_reads"] < off[1].counters["memory.mbb_reads"]
    # Space leaping without ERT hardware (VP500 with the feature on): a scene's ERT
    # threshold is honoured in the image but saves no cycle.
    vp500 = machine("volumepro500", space_leaping=True)
    ert = functional_and_cycle(
        scene_of(30, 20, transfer=sparse, render={"early_termination": 0.5}), head, vp500
    )
    assert np.array_equal(ert[1].image, ert[0].image)
    plain = functional_and_cycle(scene, head, vp500)[1]
    assert ert[1].cycles == plain.cycles and plain.cycles < off[1].cycles * 1.1


@pytest.mark.parametrize("arch", ["volumepro500", "em-cube", "volumepro1000"])
def test_sections_park_partial_rays_and_keep_the_image(head, arch):
    """Rule 7: bands of 6 beams; rays crossing a band boundary are parked off-chip and
    reloaded; overlap mini-block beams are re-read.  Compositing stays front to back."""
    for az, el in [(30, 20), (200, -35), (0, 0)]:
        scene = scene_of(az, el, render={"lighting": True})
        whole = functional_and_cycle(scene, head, arch)
        banded = functional_and_cycle(
            scene, head, machine(arch, section_width=6, section_overhead_cycles=50)
        )
        assert_identical(*whole[:2])
        assert np.array_equal(banded[1].image, whole[0].image)
        c = banded[1].counters
        assert c["section.count"] == 4
        assert c["memory.mbb_reads"] > whole[1].counters["memory.mbb_reads"]
        assert banded[1].cycles > whole[1].cycles + 3 * 50
        if (az, el) != (0, 0):
            assert c["section.parked_rays"] > 0  # sheared rays cross band boundaries


def test_a_volume_too_big_for_the_sdram_is_refused_naming_the_key(head):
    from hwsim.core.errors import InputError

    tiny = machine("volumepro500", memory={**resolve_arch("volumepro500").memory, "rows": 1})
    with pytest.raises(InputError, match=r"volumepro500.toml: memory.rows: .* \(allowed: >= 2"):
        functional_and_cycle(scene_of(30, 20), head, tiny)


def test_perspective_refuses_sections(head):
    from hwsim.core.errors import InputError

    scene = scene_of(30, 20, projection="perspective")
    with pytest.raises(InputError, match="overheads.section_width"):
        functional_and_cycle(scene, head, machine("volumepro1000", section_width=6))


def test_render_entry_point_runs_the_volumepro_machines(head):
    run = render(scene_of(30, 20), fidelity="cycle", arch="volumepro500", volume=head)
    assert run.arch == "volumepro500" and run.cycles > 0 and run.clock_hz == 125e6
    assert run.derived["samples_per_cycle"] <= 4
    assert run.counters["memory.bursts"] > 0


def test_trace_shows_the_sdram_data_buses_and_the_beams(head, tmp_path):
    from models.cycle import render_cycle as rc

    scene = scene_of(30, 20, mode="mip")
    arch = resolve_arch("volumepro500")
    tf = resolve_transfer(scene.transfer, head)
    frame = frame_of(scene, head, tf, arch)
    plain = rc(frame)
    traced = rc(frame, trace=tmp_path / "w.vcd")
    assert np.array_equal(plain.image, traced.image) and plain.cycles == traced.cycles
    text = (tmp_path / "w.vcd").read_text()
    assert "$scope module memory_3 $end" in text and "$scope module pipelines $end" in text
    assert "o__valid" in text and "i__valid" in text and "$enddefinitions $end" in text


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ct_cranium.nrrd", "mr_brainsmall.nrrd"])
def test_real_volumes_are_bit_identical(shared_data, name):
    vol = read_volume(shared_data / name)
    tf = TransferSpec(preset="auto")
    for arch, mode, view, projection in (
        ("volumepro500", "composite", (30, 15), "parallel"),
        ("volumepro1000", "composite", (20, 10), "perspective"),
    ):
        scene = scene_of(*view, size=40, mode=mode, transfer=tf, projection=projection)
        assert_identical(*functional_and_cycle(scene, vol, arch)[:2])


def test_voxel_gradients_load_slices_one_ahead_not_in_a_chain():
    # Regression: each slice's gradient planes used to load the next slice's planes,
    # gradients included, recursing through every slice (RecursionError at 256^3).
    import sys

    from hwsim.studies.figures import figure_scene

    scene = figure_scene(40)
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(120)  # far below 40 slices x the old chain's frames
    try:
        run = render(scene, fidelity="cycle", arch="volumepro1000")
    finally:
        sys.setrecursionlimit(limit)
    ref = render(scene, fidelity="functional", arch="volumepro1000")
    assert np.array_equal(run.image, ref.image)
